#include "tagsfm/eval/similarity.h"

#include <Eigen/Geometry>
#include <Eigen/SVD>

namespace tagsfm::eval {

Rigid3d Sim3d::TransformPose(const Rigid3d& cam_from_est_world) const {
  // x_cam = R_c x_est + t_c and x_est = R^T (x_true - t) / s, so with the
  // camera frame scaled by s: x_cam' = R_c R^T x_true + (s t_c - R_c R^T t).
  const Eigen::Quaterniond rotation_out = cam_from_est_world.rotation * rotation.conjugate();
  return Rigid3d(rotation_out, scale * cam_from_est_world.translation - (rotation_out * translation));
}

Result<Sim3d> EstimateSim3d(const std::vector<Eigen::Vector3d>& src, const std::vector<Eigen::Vector3d>& dst,
                            bool with_scale) {
  if (src.size() != dst.size()) return MakeError("alignment: point sets differ in size");
  if (src.size() < 3) return MakeError("alignment: needs at least 3 corresponding points");
  Eigen::Matrix3Xd a(3, src.size()), b(3, dst.size());
  for (size_t i = 0; i < src.size(); ++i) {
    a.col(static_cast<Eigen::Index>(i)) = src[i];
    b.col(static_cast<Eigen::Index>(i)) = dst[i];
  }
  // Degenerate (collinear or coincident) sets leave the rotation undetermined.
  const Eigen::Matrix3Xd centred = a.colwise() - a.rowwise().mean();
  const Eigen::Vector3d spread = Eigen::JacobiSVD<Eigen::Matrix3Xd>(centred).singularValues();
  if (spread(1) <= 1e-9 * std::max(1.0, spread(0))) return MakeError("alignment: the points are collinear");
  const Eigen::Matrix4d t = Eigen::umeyama(a, b, with_scale);
  Sim3d sim;
  const Eigen::Matrix3d scaled_rotation = t.topLeftCorner<3, 3>();
  sim.scale = with_scale ? std::cbrt(scaled_rotation.determinant()) : 1.0;
  sim.rotation = Eigen::Quaterniond(scaled_rotation / sim.scale).normalized();
  sim.translation = t.topRightCorner<3, 1>();
  return sim;
}

}  // namespace tagsfm::eval
