#pragma once
// Feature points from tracks and known camera poses (the targets give the
// poses, so the points come out metric): linear triangulation (DLT) to
// start, then the minimum of the angular error between each observed ray and
// the direction to the point, which unlike the reprojection error weighs
// every view alike however far the point is from the image centre, and does
// not break down for points near a camera's image plane.
#include <array>
#include <cstdint>
#include <optional>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "tagsfm/core/camera_model.h"
#include "tagsfm/core/csv_formats.h"
#include "tagsfm/core/result.h"
#include "tagsfm/core/rigid3d.h"
#include "tagsfm/feature/feature_set.h"

namespace tagsfm {

struct FeatureTriangulationOptions {
  int min_track_length = 3;        // views of a point; 2 give no check of the match
  double min_angle_deg = 3.0;      // widest angle between the point's rays: below, depth is 20x worse than lateral
  double max_reprojection_px = 2.0;  // RMS over the track after refinement
  int max_iterations = 10;

  Status Check() const;
};

struct FeaturePoint {
  TrackId track = -1;
  Eigen::Vector3d position = Eigen::Vector3d::Zero();  // world frame, metres
  std::array<std::uint8_t, 3> rgb{0, 0, 0};
  double reprojection_rms_px = 0;
  double max_angle_deg = 0;
  // Position covariance, m^2, from the rays' angular noise (the point's own
  // reprojection RMS, at least 0.1 px, over fx): the poses' uncertainty is
  // left out (from 100+ target corners they are far better known than a
  // point from a few rays).
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
  std::vector<std::pair<FrameId, Eigen::Vector2d>> observations;  // frame, pixel
};

// One ray per view: the camera's pose and the unit direction of the
// observation in the camera frame.
struct FeatureRay {
  Rigid3d cam_from_world;
  Eigen::Vector3d bearing = Eigen::Vector3d::UnitZ();
  // Inverse variance of this ray's angular noise relative to the others'
  // (1: alike); a view located twice as badly weighs a quarter.
  double weight = 1.0;
};

// Linear (DLT) triangulation in normalised coordinates; nullopt when the
// rays are (nearly) parallel.
std::optional<Eigen::Vector3d> TriangulateLinear(const std::vector<FeatureRay>& rays);

// Gauss-Newton on the weighted angular error (tangent-plane residual of
// each ray) from `start`.
Eigen::Vector3d RefineAngularError(const std::vector<FeatureRay>& rays, const Eigen::Vector3d& start, int max_iterations);

// Normal matrix J^T W J of the angular residuals at `point` (angular
// noise sigma^2 / weight): its inverse times sigma^2 is the point's covariance.
Eigen::Matrix3d AngularNormalMatrix(const std::vector<FeatureRay>& rays, const Eigen::Vector3d& point);

// Every track seen in at least min_track_length registered frames, whose
// rays are wide enough apart, in front of every camera, and reprojecting
// within max_reprojection_px.
std::vector<FeaturePoint> TriangulateFeatureTracks(const std::vector<FeatureSet>& sets, const PoseMap& cam_from_world,
                                                   const CameraModel& camera, const FeatureTriangulationOptions& options);

}  // namespace tagsfm
