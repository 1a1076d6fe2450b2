#pragma once
// A camera at `centre` looking at `target`, y down as in images: the poses
// of the synthetic sfm tests.
#include "tagsfm/core/rigid3d.h"

namespace tagsfm::sfm {

inline Rigid3d LookingAt(const Eigen::Vector3d& centre, const Eigen::Vector3d& target) {
  const Eigen::Vector3d z = (target - centre).normalized();
  const Eigen::Vector3d x = Eigen::Vector3d::UnitY().cross(z).normalized();
  const Eigen::Vector3d y = z.cross(x);
  Eigen::Matrix3d world_from_cam;
  world_from_cam << x, y, z;
  const Eigen::Matrix3d r = world_from_cam.transpose();
  return Rigid3d(Eigen::Quaterniond(r), -(r * centre));
}

}  // namespace tagsfm::sfm
