#pragma once
// A rigid transform named by what it maps, as in COLMAP: `cam_from_world`
// takes a world point to the camera frame, X_cam = R X_world + t.
#include <Eigen/Core>
#include <Eigen/Geometry>

namespace tagsfm {

struct Rigid3d {
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();

  Rigid3d() = default;
  Rigid3d(const Eigen::Quaterniond& r, const Eigen::Vector3d& t) : rotation(r.normalized()), translation(t) {}

  Eigen::Vector3d operator*(const Eigen::Vector3d& point) const { return rotation * point + translation; }
  // (a_from_b * b_from_c) is a_from_c.
  Rigid3d operator*(const Rigid3d& other) const {
    return Rigid3d(rotation * other.rotation, rotation * other.translation + translation);
  }
  Rigid3d Inverse() const {
    const Eigen::Quaterniond inv = rotation.conjugate();
    return Rigid3d(inv, -(inv * translation));
  }
  // For cam_from_world: the camera centre in world coordinates.
  Eigen::Vector3d Center() const { return -(rotation.conjugate() * translation); }
  Eigen::Matrix3d RotationMatrix() const { return rotation.toRotationMatrix(); }
};

// Angle of the rotation between two orientations, in degrees.
double RotationAngleDeg(const Eigen::Quaterniond& a, const Eigen::Quaterniond& b);

}  // namespace tagsfm
