#include "tagsfm/feature/held_pose_refinement.h"

#include <cmath>
#include <map>

#include <Eigen/Cholesky>

#include "parallel_for.h"

namespace tagsfm {
namespace {

// A view as the point's error needs it: the camera's rotation and
// translation and the observation undistorted to normalised coordinates.
struct HeldView {
  Eigen::Matrix3d r;
  Eigen::Vector3d t;
  Eigen::Vector2d observed;
};

// The Huber cost of the views' pixel residuals at x; false when x lies
// behind one of the cameras.
bool HuberCost(const std::vector<HeldView>& views, const Eigen::Vector3d& x, double fx, double fy, double huber,
               double* cost) {
  *cost = 0;
  for (const HeldView& v : views) {
    const Eigen::Vector3d p = v.r * x + v.t;
    if (!(p.z() > 0)) return false;
    const double s = Eigen::Vector2d(fx * (p.x() / p.z() - v.observed.x()), fy * (p.y() / p.z() - v.observed.y())).squaredNorm();
    *cost += s <= huber * huber ? s : 2 * huber * std::sqrt(s) - huber * huber;
  }
  return true;
}

// Gauss-Newton with the Huber loss as weights (iteratively reweighted),
// halving a step that does not lower the cost.
void RefineOne(const std::vector<HeldView>& views, double fx, double fy, const HeldPoseRefinementOptions& options,
               FeaturePoint* point) {
  const double huber = options.huber_px;
  Eigen::Vector3d x = point->position;
  double cost = 0;
  if (views.empty() || !HuberCost(views, x, fx, fy, huber, &cost)) return;
  for (int iteration = 0; iteration < options.max_iterations; ++iteration) {
    Eigen::Matrix3d h = Eigen::Matrix3d::Zero();
    Eigen::Vector3d g = Eigen::Vector3d::Zero();
    for (const HeldView& v : views) {
      const Eigen::Vector3d p = v.r * x + v.t;
      const double iz = 1.0 / p.z();
      const Eigen::Vector2d r(fx * (p.x() * iz - v.observed.x()), fy * (p.y() * iz - v.observed.y()));
      Eigen::Matrix<double, 2, 3> d_p;
      d_p << fx * iz, 0, -fx * p.x() * iz * iz, 0, fy * iz, -fy * p.y() * iz * iz;
      const Eigen::Matrix<double, 2, 3> j = d_p * v.r;
      const double norm = r.norm();
      const double w = norm <= huber ? 1.0 : huber / norm;
      h.noalias() += w * j.transpose() * j;
      g.noalias() += w * j.transpose() * r;
    }
    const Eigen::LDLT<Eigen::Matrix3d> ldlt(h);
    if (ldlt.info() != Eigen::Success) break;
    Eigen::Vector3d step = -ldlt.solve(g);
    if (!step.allFinite()) break;
    bool lowered = false;
    for (int halving = 0; halving < 6 && !lowered; ++halving, step *= 0.5) {
      double next_cost = 0;
      if (HuberCost(views, x + step, fx, fy, huber, &next_cost) && next_cost <= cost) {
        x += step;
        cost = next_cost;
        lowered = true;
      }
    }
    if (!lowered || step.norm() <= 1e-12 * (1.0 + x.norm())) break;
  }
  point->position = x;
}

}  // namespace

void RefinePointsOnHeldPoses(const PoseMap& cam_from_world, const CameraModel& camera,
                             const HeldPoseRefinementOptions& options, const std::vector<size_t>& which,
                             std::vector<FeaturePoint>* points) {
  std::map<FrameId, std::pair<Eigen::Matrix3d, Eigen::Vector3d>> poses;
  for (const auto& [frame, pose] : cam_from_world) poses[frame] = {pose.RotationMatrix(), pose.translation};
  ParallelFor(which.size(), options.threads, [&](size_t k) {
    FeaturePoint& point = (*points)[which[k]];
    std::vector<HeldView> views;
    views.reserve(point.observations.size());
    for (const auto& [frame, pixel] : point.observations) {
      const auto it = poses.find(frame);
      if (it != poses.end()) views.push_back({it->second.first, it->second.second, camera.PixelToNormalized(pixel)});
    }
    RefineOne(views, camera.fx, camera.fy, options, &point);
  }, 64);
}

}  // namespace tagsfm
