#pragma once
// The synthetic scenes of the experiments: the paper's 1x1x1 box (section
// 4.1) and two vehicle-sized objects standing in for the paper's bradley and
// maxxpro models (section 4.2), which are not public: hulls of boxes and
// cylinders of about the real vehicles' size (units ~ metres), seen by sets
// of 1234 and 278 cameras on a hemisphere around them, as the paper's
// rendered sequences were.
#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "tagsfm/core/camera_model.h"
#include "tagsfm/core/rigid3d.h"

namespace tagsfm::analysis {

struct SurfacePoint {
  Eigen::Vector3d position;
  Eigen::Vector3d normal;  // outward, unit
};

// The camera of every experiment: 1280x960 px, focal 1000 px, no distortion.
CameraModel ExperimentCamera();

// `count` points uniformly on the surface of an axis-aligned cube of edge
// `edge` centred at the origin.
std::vector<SurfacePoint> BoxSurfacePoints(int count, double edge, std::mt19937& rng);

enum class VehicleKind { kBradleyLike, kMaxxproLike };

struct SyntheticObject {
  std::string name;                    // "bradley-like", "maxxpro-like"
  std::vector<SurfacePoint> surface;   // dense points on the hull
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  std::vector<Rigid3d> cameras;        // cam_from_world, on a hemisphere around
};

// bradley-like: 6.5 x 3.2 x 2.7 tracked hull with turret and gun, 1234
// cameras; maxxpro-like: 6.4 x 2.5 x 2.9 wheeled truck, 278 cameras.
SyntheticObject MakeVehicle(VehicleKind kind, std::uint32_t seed);

// Indices of the surface points a camera sees: in front of it, inside the
// image, on a face turned towards it. (Back-face culling only, no occlusion
// test between parts: the hulls are nearly convex.)
std::vector<int> VisiblePoints(const std::vector<SurfacePoint>& surface, const Rigid3d& cam_from_world,
                               const CameraModel& camera);

// Pixels of world points (distortion-free camera, pixel centres at integers).
Eigen::Vector2d ProjectToPixel(const CameraModel& camera, const Eigen::Vector3d& point_in_cam);

}  // namespace tagsfm::analysis
