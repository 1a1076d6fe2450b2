#pragma once
// A rigid transform stored as the flat arrays Ceres optimises: a unit
// quaternion in Eigen's order (x, y, z, w; Ceres' EigenQuaternionManifold)
// and a translation. Lives at a stable address while a problem refers to it.
#include "tagsfm/core/rigid3d.h"

namespace tagsfm {

struct PoseParams {
  double q[4] = {0, 0, 0, 1};  // x, y, z, w
  double t[3] = {0, 0, 0};

  PoseParams() = default;
  explicit PoseParams(const Rigid3d& pose) { Set(pose); }
  void Set(const Rigid3d& pose) {
    const Eigen::Quaterniond r = pose.rotation.normalized();
    q[0] = r.x(); q[1] = r.y(); q[2] = r.z(); q[3] = r.w();
    t[0] = pose.translation.x(); t[1] = pose.translation.y(); t[2] = pose.translation.z();
  }
  Rigid3d ToRigid() const {
    return Rigid3d(Eigen::Quaterniond(q[3], q[0], q[1], q[2]), Eigen::Vector3d(t[0], t[1], t[2]));
  }
};

}  // namespace tagsfm
