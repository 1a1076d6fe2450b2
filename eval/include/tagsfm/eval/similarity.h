#pragma once
// Best-fit rigid and similarity transforms between corresponding point sets
// (Umeyama 1991), and how they carry an estimated result into the true frame.
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "tagsfm/core/result.h"
#include "tagsfm/core/rigid3d.h"

namespace tagsfm::eval {

// x_true = scale * R x_est + t.
struct Sim3d {
  double scale = 1.0;
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();

  Eigen::Vector3d operator*(const Eigen::Vector3d& point) const { return scale * (rotation * point) + translation; }
  // An estimated camera pose (cam_from_est_world) as cam_from_true_world;
  // the camera frame is scaled with the world so projections are unchanged.
  Rigid3d TransformPose(const Rigid3d& cam_from_est_world) const;
};

// Least-squares fit of dst ~ T(src), with or without scale. Needs at least 3
// non-collinear correspondences; otherwise an error.
Result<Sim3d> EstimateSim3d(const std::vector<Eigen::Vector3d>& src, const std::vector<Eigen::Vector3d>& dst,
                            bool with_scale);

}  // namespace tagsfm::eval
