#pragma once
// The paper's error metrics (section 4.1, eq. 1-3).
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "tagsfm/core/rigid3d.h"

namespace tagsfm::analysis {

// Eq. 1: |P X - x| in pixels, averaged over the points: how far the points
// project with the estimated pose from where they were observed.
// `project` maps a point in the camera frame to pixels.
template <class Project>
double MeanReprojectionError(const Rigid3d& cam_from_world, const std::vector<Eigen::Vector3d>& points_in_world,
                             const std::vector<Eigen::Vector2d>& observed_px, const Project& project) {
  double sum = 0;
  for (size_t i = 0; i < points_in_world.size(); ++i) {
    sum += (project(cam_from_world * points_in_world[i]) - observed_px[i]).norm();
  }
  return points_in_world.empty() ? 0.0 : sum / static_cast<double>(points_in_world.size());
}

// Eq. 2: |q_i - q_j| / |q_j| on unit quaternions, with q_i's sign chosen to
// match q_j (q and -q are the same rotation). Equals 2 sin(angle / 4).
double RotationalError(const Eigen::Quaterniond& estimated, const Eigen::Quaterniond& truth);

// Eq. 3: |X_i - X_j|.
inline double PositionalError(const Eigen::Vector3d& a, const Eigen::Vector3d& b) { return (a - b).norm(); }

// Eq. 2 and 3 for two camera poses (cam_from_world), plus the angle in degrees.
struct PoseErrors {
  double rotation_eq2 = 0;
  double rotation_deg = 0;
  double position = 0;  // camera centres
};
PoseErrors ComparePoses(const Rigid3d& estimated_cam_from_world, const Rigid3d& true_cam_from_world);

}  // namespace tagsfm::analysis
