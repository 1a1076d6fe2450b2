#pragma once
// A rigid transform stored as the flat array Ceres optimises: one parameter
// block of 7, a unit quaternion in Eigen's order (x, y, z, w) then the
// translation (PoseManifold in cost_functions.h: tangent [rotation (3),
// translation (3)]). One block per pose rather than two, so that a Schur
// solver can eliminate a whole tag (or camera) at once. Lives at a stable
// address while a problem refers to it.
#include "tagsfm/core/rigid3d.h"

namespace tagsfm {

struct PoseParams {
  double data[7] = {0, 0, 0, 1, 0, 0, 0};  // qx, qy, qz, qw, tx, ty, tz

  PoseParams() = default;
  explicit PoseParams(const Rigid3d& pose) { Set(pose); }
  void Set(const Rigid3d& pose) {
    const Eigen::Quaterniond r = pose.rotation.normalized();
    data[0] = r.x(); data[1] = r.y(); data[2] = r.z(); data[3] = r.w();
    data[4] = pose.translation.x(); data[5] = pose.translation.y(); data[6] = pose.translation.z();
  }
  Rigid3d ToRigid() const {
    return Rigid3d(Eigen::Quaterniond(data[3], data[0], data[1], data[2]), Eigen::Vector3d(data[4], data[5], data[6]));
  }
};

}  // namespace tagsfm
