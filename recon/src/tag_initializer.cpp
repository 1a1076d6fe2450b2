#include "tagsfm/recon/tag_initializer.h"

#include <cmath>

#include <ceres/ceres.h>

#include "tagsfm/recon/cost_functions.h"
#include "tagsfm/recon/tag_geometry.h"

namespace tagsfm {
namespace {

// Sum of squared pixel errors of a tag pose in one camera; false when the
// tag is behind the camera or turned away from it.
bool TagErrorInView(const Rigid3d& world_from_tag, double size_m, const Rigid3d& cam_from_world,
                    const TagObservation& obs, double fx, double fy, double* sum_sq) {
  const Rigid3d cam_from_tag = cam_from_world * world_from_tag;
  // The printed face (+z of the tag) must face the camera: the camera centre
  // in the tag frame has z > 0.
  if (cam_from_tag.Inverse().translation.z() <= 0) return false;
  for (int k = 0; k < 4; ++k) {
    const Eigen::Vector3d p = cam_from_tag * TagCornerInTag(k, size_m);
    if (p.z() <= 0) return false;
    const double ex = fx * (p.x() / p.z() - obs.normalized[k].x());
    const double ey = fy * (p.y() / p.z() - obs.normalized[k].y());
    *sum_sq += ex * ex + ey * ey;
  }
  return true;
}

double NormalizedArea(const TagObservation& obs) {
  double area = 0;
  for (int k = 0; k < 4; ++k) {
    const auto& a = obs.normalized[k];
    const auto& b = obs.normalized[(k + 1) % 4];
    area += a.x() * b.y() - b.x() * a.y();
  }
  return std::abs(0.5 * area);
}

}  // namespace

double TagPoseRmsPx(const Rigid3d& world_from_tag, double size_m, const std::vector<TagView>& views, double fx,
                    double fy) {
  if (views.empty()) return INFINITY;
  double sum = 0;
  for (const auto& v : views) {
    if (!TagErrorInView(world_from_tag, size_m, v.frame->cam_from_world.ToRigid(), *v.observation, fx, fy, &sum)) {
      return INFINITY;
    }
  }
  return std::sqrt(sum / (4.0 * static_cast<double>(views.size())));
}

std::optional<TagInitialization> InitializeTag(const std::vector<TagView>& views, double size_m, double fx, double fy) {
  if (views.empty()) return std::nullopt;
  // Candidates from the most recent views are enough: each gives the two
  // IPPE poses, and the right one fits every view.
  const size_t first = views.size() > 6 ? views.size() - 6 : 0;
  std::optional<TagInitialization> best;
  for (size_t i = first; i < views.size(); ++i) {
    const Rigid3d world_from_cam = views[i].frame->cam_from_world.ToRigid().Inverse();
    for (const Rigid3d& cam_from_tag : TagPoseCandidates(views[i].observation->normalized, size_m)) {
      const Rigid3d candidate = world_from_cam * cam_from_tag;
      const double rms = TagPoseRmsPx(candidate, size_m, views, fx, fy);
      if (std::isfinite(rms) && (!best || rms < best->rms_px)) best = TagInitialization{candidate, rms};
    }
  }
  if (!best) return std::nullopt;

  // Refine the tag's pose over all views, the cameras fixed.
  PoseParams tag(best->world_from_tag);
  std::vector<PoseParams> cams;
  cams.reserve(views.size());
  ceres::Problem problem;
  for (const auto& v : views) {
    cams.push_back(v.frame->cam_from_world);
    problem.AddResidualBlock(TagReprojectionError::Create(v.observation->normalized, size_m, fx, fy),
                             new ceres::HuberLoss(2.0), cams.back().data, tag.data);
    problem.SetParameterBlockConstant(cams.back().data);
  }
  problem.SetManifold(tag.data, new PoseManifold);
  ceres::Solver::Options options;
  options.linear_solver_type = ceres::DENSE_QR;
  options.max_num_iterations = 20;
  options.logging_type = ceres::SILENT;
  ceres::Solver::Summary summary;
  ceres::Solve(options, &problem, &summary);
  if (summary.IsSolutionUsable()) {
    const Rigid3d refined = tag.ToRigid();
    const double rms = TagPoseRmsPx(refined, size_m, views, fx, fy);
    if (std::isfinite(rms) && rms <= best->rms_px) best = TagInitialization{refined, rms};
  }
  return best;
}

double MaxViewAngleDeg(const std::vector<TagView>& views, const Eigen::Vector3d& point_in_world) {
  double max_angle = 0;
  std::vector<Eigen::Vector3d> rays;
  rays.reserve(views.size());
  for (const auto& v : views) rays.push_back((v.frame->cam_from_world.ToRigid().Center() - point_in_world).normalized());
  for (size_t i = 0; i < rays.size(); ++i) {
    for (size_t j = i + 1; j < rays.size(); ++j) {
      max_angle = std::max(max_angle, std::acos(std::clamp(rays[i].dot(rays[j]), -1.0, 1.0)));
    }
  }
  return max_angle * 180.0 / M_PI;
}

std::optional<TwoViewBootstrap> BootstrapFromTwoViews(const FrameState& first, const FrameState& second,
                                                      const std::map<TagId, double>& size_by_tag, double fx,
                                                      double fy) {
  std::vector<std::pair<const TagObservation*, const TagObservation*>> shared;
  for (const auto& obs : first.tags) {
    if (const TagObservation* other = second.Find(obs.id); other && size_by_tag.count(obs.id)) {
      shared.emplace_back(&obs, other);
    }
  }
  if (shared.size() < 2) return std::nullopt;
  // The anchor: the shared tag seen largest in the worse of the two views.
  size_t anchor_index = 0;
  double anchor_area = -1;
  for (size_t i = 0; i < shared.size(); ++i) {
    const double area = std::min(NormalizedArea(*shared[i].first), NormalizedArea(*shared[i].second));
    if (area > anchor_area) {
      anchor_area = area;
      anchor_index = i;
    }
  }
  const TagId anchor = shared[anchor_index].first->id;
  const double anchor_size = size_by_tag.at(anchor);
  const auto first_candidates = TagPoseCandidates(shared[anchor_index].first->normalized, anchor_size);
  const auto second_candidates = TagPoseCandidates(shared[anchor_index].second->normalized, anchor_size);

  std::optional<TwoViewBootstrap> best;
  double best_sum = INFINITY;
  for (const Rigid3d& cam1 : first_candidates) {
    for (const Rigid3d& cam2 : second_candidates) {
      FrameState view1, view2;
      view1.cam_from_world.Set(cam1);
      view2.cam_from_world.Set(cam2);
      TwoViewBootstrap attempt;
      attempt.anchor = anchor;
      attempt.first_cam_from_world = cam1;
      attempt.second_cam_from_world = cam2;
      double sum = 0;
      int corners = 0;
      bool ok = true;
      for (const auto& [obs1, obs2] : shared) {
        const double size = size_by_tag.at(obs1->id);
        const std::vector<TagView> views{{&view1, obs1}, {&view2, obs2}};
        if (obs1->id == anchor) {
          attempt.world_from_tag[anchor] = Rigid3d();
          const double rms = TagPoseRmsPx(Rigid3d(), size, views, fx, fy);
          sum += rms * rms * 8;
          corners += 8;
          continue;
        }
        std::optional<Rigid3d> tag_best;
        double tag_rms = INFINITY;
        for (const auto& [view, obs] : {std::pair{&view1, obs1}, std::pair{&view2, obs2}}) {
          const Rigid3d world_from_cam = view->cam_from_world.ToRigid().Inverse();
          for (const Rigid3d& cam_from_tag : TagPoseCandidates(obs->normalized, size)) {
            const double rms = TagPoseRmsPx(world_from_cam * cam_from_tag, size, views, fx, fy);
            if (rms < tag_rms) {
              tag_rms = rms;
              tag_best = world_from_cam * cam_from_tag;
            }
          }
        }
        if (!tag_best) {
          ok = false;
          break;
        }
        attempt.world_from_tag[obs1->id] = *tag_best;
        sum += tag_rms * tag_rms * 8;
        corners += 8;
      }
      if (!ok || corners == 0 || !(sum < best_sum)) continue;
      best_sum = sum;
      attempt.rms_px = std::sqrt(sum / corners);
      const Eigen::Vector3d ray1 = cam1.Inverse().translation.normalized();
      const Eigen::Vector3d ray2 = cam2.Inverse().translation.normalized();
      attempt.view_angle_deg = std::acos(std::clamp(ray1.dot(ray2), -1.0, 1.0)) * 180.0 / M_PI;
      best = attempt;
    }
  }
  return best;
}

}  // namespace tagsfm
