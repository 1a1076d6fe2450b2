#pragma once
// A synthetic scene: textured planar rectangles with AprilTag targets on them.
// World frame: metres, z up, the floor (if any) at z = 0.
#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "tagsfm/core/csv_formats.h"
#include "tagsfm/core/result.h"

namespace tagsfm::synth {

// A rectangle origin + a*edge_u + b*edge_v, a, b in [0, 1]. The edges are
// orthogonal; the face's front (the side that is textured and seen) is
// towards edge_u x edge_v.
struct Rectangle3d {
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();
  Eigen::Vector3d edge_u = Eigen::Vector3d::UnitX();
  Eigen::Vector3d edge_v = Eigen::Vector3d::UnitY();

  Eigen::Vector3d Normal() const { return edge_u.cross(edge_v).normalized(); }
  // A point given in metres along edge_u and edge_v from the origin.
  Eigen::Vector3d PointAt(const Eigen::Vector2d& in_face_m) const {
    return origin + edge_u.normalized() * in_face_m.x() + edge_v.normalized() * in_face_m.y();
  }
  // Euclidean distance from a point to the rectangle (not the infinite plane).
  double DistanceTo(const Eigen::Vector3d& point) const;
};

// The modules of one tag as libapriltag draws it (apriltag_to_image): a
// total_width x total_width grid, row 0 at the top, true = white. The
// detector's quad, whose corners are the targets' corners, is the square of
// width_at_border modules centred in the grid; `size_m` of a tag is the edge of
// that square (for tag36h11 the outer edge of the black square: 8 of the 10
// modules, the outermost ring being white).
struct TagPattern {
  int total_width = 0;
  int width_at_border = 0;
  std::vector<std::uint8_t> white;  // row-major, total_width^2

  bool WhiteAt(int col, int row) const { return white[static_cast<size_t>(row * total_width + col)] != 0; }
};

// A tag stuck on a face: its centre in metres along the face's edges, and the
// angle of its "right" direction from edge_u (its "up" is 90 degrees further,
// so the tag is seen upright from the face's front).
struct PlacedTag {
  TagId id = 0;
  int face = 0;
  Eigen::Vector2d centre_in_face = Eigen::Vector2d::Zero();
  double angle_rad = 0.0;
  double size_m = 0.06;
  // White modules round the detector's square (SynthOptions::tag_margin);
  // never less than the pattern's own outer ring.
  double margin_modules = 1.0;
  TagPattern pattern;
};

struct SceneFace {
  std::string name;
  Rectangle3d rect;
  double shade = 1.0;   // lighting factor of the whole face (faces differ, like under a lamp)
  cv::Mat1f texture;    // albedo in [0, 1]; column along edge_u, row along edge_v
};

struct Scene {
  std::string name;
  std::string family;
  std::vector<SceneFace> faces;
  std::vector<PlacedTag> tags;
  Eigen::Vector3d look_at = Eigen::Vector3d::Zero();  // what the camera paths aim at
  double background = 0.5;                            // albedo where a ray hits nothing
};

// The corners of a placed tag in the world frame, in libapriltag's order
// (seen from the front, upright: bottom-left, bottom-right, top-right, top-left).
TagCorners TagCornersInWorld(const Scene& scene, const PlacedTag& tag);
TargetCornerMap SceneTargets(const Scene& scene);

}  // namespace tagsfm::synth
