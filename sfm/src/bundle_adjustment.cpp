#include "tagsfm/sfm/bundle_adjustment.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <set>

#include <ceres/ceres.h>
#include <ceres/sphere_manifold.h>

namespace tagsfm::sfm {

Status BundleOptions::Check() const {
  if (!(fx > 0 && fy > 0)) return MakeError("sfm: the camera's focal lengths must be > 0");
  if (!(huber_px > 0)) return MakeError("sfm.huber_px must be > 0");
  if (max_iterations < 1) return MakeError("sfm.max_iterations must be >= 1");
  if (threads < 1) return MakeError("sfm.threads must be >= 1");
  return Status::Ok();
}

namespace {

// Reprojection residual in (undistorted) pixels of one observation.
struct ReprojectionCost {
  Eigen::Vector2d observed;
  double fx, fy;

  template <class T>
  bool operator()(const T* rotation, const T* translation, const T* point, T* residual) const {
    const Eigen::Map<const Eigen::Quaternion<T>> r(rotation);
    const Eigen::Map<const Eigen::Matrix<T, 3, 1>> t(translation), x(point);
    const Eigen::Matrix<T, 3, 1> p = r * x + t;
    residual[0] = T(fx) * (p.x() / p.z() - T(observed.x()));
    residual[1] = T(fy) * (p.y() / p.z() - T(observed.y()));
    return true;
  }
};

struct CameraBlock {
  double q[4];  // x, y, z, w (Eigen's order)
  double t[3];
};

}  // namespace

BundleSummary AdjustBundle(SfmModel* model, const std::vector<ImageIdx>& variable, const BundleOptions& options) {
  BundleSummary out;
  if (!options.Check()) return out;
  std::set<ImageIdx> free_images;
  for (ImageIdx i = 0; i < static_cast<ImageIdx>(model->images.size()); ++i) {
    if (model->images[i].registered && (variable.empty() || std::count(variable.begin(), variable.end(), i))) {
      free_images.insert(i);
    }
  }
  std::set<PointIdx> point_ids;
  for (ImageIdx i : free_images) {
    for (PointIdx p : model->images[i].point_of_feature) {
      if (p >= 0) point_ids.insert(p);
    }
  }
  std::map<ImageIdx, CameraBlock> cameras;
  std::map<PointIdx, Eigen::Vector3d> points;
  ceres::Problem::Options problem_options;
  problem_options.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::Problem problem(problem_options);
  ceres::EigenQuaternionManifold quaternion_manifold;
  ceres::SphereManifold<3> sphere_manifold;
  ceres::HuberLoss* loss = new ceres::HuberLoss(options.huber_px);
  for (PointIdx p : point_ids) {
    const SfmPoint& point = model->points[p];
    if (point.track.size() < 2) continue;
    Eigen::Vector3d& x = points.emplace(p, point.xyz).first->second;
    for (const Observation& obs : point.track) {
      const SfmImage& image = model->images[obs.image];
      if (!image.registered) continue;
      auto [it, fresh] = cameras.try_emplace(obs.image);
      if (fresh) {
        const Eigen::Quaterniond r = image.cam_from_world.rotation;
        it->second = {{r.x(), r.y(), r.z(), r.w()}, {image.cam_from_world.translation.x(),
                                                      image.cam_from_world.translation.y(),
                                                      image.cam_from_world.translation.z()}};
      }
      auto* cost = new ceres::AutoDiffCostFunction<ReprojectionCost, 2, 4, 3, 3>(
          new ReprojectionCost{image.normalized[obs.feature], options.fx, options.fy});
      problem.AddResidualBlock(cost, loss, it->second.q, it->second.t, x.data());
      ++out.residuals;
    }
  }
  if (out.residuals == 0) return out;
  for (auto& [i, block] : cameras) {
    problem.SetManifold(block.q, &quaternion_manifold);
    const bool is_free = free_images.count(i) && i != model->gauge_origin;
    if (!is_free) {
      problem.SetParameterBlockConstant(block.q);
      problem.SetParameterBlockConstant(block.t);
    } else if (i == model->gauge_scale) {
      problem.SetManifold(block.t, &sphere_manifold);  // its distance from the origin camera is the scale
    }
  }
  ceres::Solver::Options solver;
  solver.linear_solver_type = ceres::DENSE_SCHUR;
  solver.max_num_iterations = options.max_iterations;
  solver.num_threads = options.threads;
  solver.function_tolerance = 1e-6;
  solver.logging_type = ceres::SILENT;
  ceres::Solver::Summary summary;
  ceres::Solve(solver, &problem, &summary);
  out.usable = summary.IsSolutionUsable();
  out.images = static_cast<int>(free_images.size());
  out.points = static_cast<int>(points.size());
  out.initial_rms_px = std::sqrt(2 * summary.initial_cost / out.residuals);
  out.final_rms_px = std::sqrt(2 * summary.final_cost / out.residuals);
  if (!out.usable) return out;
  for (const auto& [i, block] : cameras) {
    if (!free_images.count(i)) continue;
    model->images[i].cam_from_world = Rigid3d(Eigen::Quaterniond(block.q[3], block.q[0], block.q[1], block.q[2]),
                                              Eigen::Vector3d(block.t[0], block.t[1], block.t[2]));
  }
  for (const auto& [p, x] : points) model->points[p].xyz = x;
  return out;
}

}  // namespace tagsfm::sfm
