#include "tagsfm/analysis/metrics.h"

namespace tagsfm::analysis {

double RotationalError(const Eigen::Quaterniond& estimated, const Eigen::Quaterniond& truth) {
  Eigen::Vector4d q_i = estimated.normalized().coeffs();
  const Eigen::Vector4d q_j = truth.normalized().coeffs();
  if (q_i.dot(q_j) < 0) q_i = -q_i;
  return (q_i - q_j).norm() / q_j.norm();
}

PoseErrors ComparePoses(const Rigid3d& estimated_cam_from_world, const Rigid3d& true_cam_from_world) {
  PoseErrors errors;
  errors.rotation_eq2 = RotationalError(estimated_cam_from_world.rotation, true_cam_from_world.rotation);
  errors.rotation_deg = RotationAngleDeg(estimated_cam_from_world.rotation, true_cam_from_world.rotation);
  errors.position = PositionalError(estimated_cam_from_world.Center(), true_cam_from_world.Center());
  return errors;
}

}  // namespace tagsfm::analysis
