// Reconstructor::TriangulateAndAdjust: the feature points triangulated on the
// target-anchored poses and adjusted with them, again while the poses move.

#include "tagsfm/recon/reconstructor.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numeric>

#include "tagsfm/feature/held_pose_refinement.h"

namespace tagsfm {

namespace {

// The tie points of the adjustment with the points. Each keyframe's image
// is cut in 8 x 8 cells, and the points are taken in order of views (most
// first), then of reprojection error (least first), while a cell they are
// seen in has fewer than per_keyframe / 64: points spread over the image
// fix a pose that points taken by views alone leave less well (box_small:
// 95.3 % of the points within 2 mm instead of 95.7; docs/features.md).
// Indices into `points`, ascending; all of them for per_keyframe 0.
std::vector<size_t> TiePoints(const std::vector<FeaturePoint>& points, int per_keyframe, const CameraModel& camera) {
  std::vector<size_t> order(points.size());
  std::iota(order.begin(), order.end(), size_t{0});
  if (per_keyframe <= 0) return order;
  std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) {
    const size_t va = points[a].observations.size(), vb = points[b].observations.size();
    if (va != vb) return va > vb;
    return points[a].reprojection_rms_px < points[b].reprojection_rms_px;
  });
  constexpr int kCells = 8;
  const int per_cell = std::max(1, per_keyframe / (kCells * kCells));
  auto cell_of = [&](const std::pair<FrameId, Eigen::Vector2d>& view) {
    const int x = std::clamp(static_cast<int>(view.second.x() * kCells / camera.width), 0, kCells - 1);
    const int y = std::clamp(static_cast<int>(view.second.y() * kCells / camera.height), 0, kCells - 1);
    return std::make_pair(view.first, y * kCells + x);
  };
  std::map<std::pair<FrameId, int>, int> taken;
  std::vector<size_t> tie;
  for (size_t i : order) {
    bool needed = false;
    for (const auto& view : points[i].observations) needed = needed || taken[cell_of(view)] < per_cell;
    if (!needed) continue;
    for (const auto& view : points[i].observations) ++taken[cell_of(view)];
    tie.push_back(i);
  }
  std::sort(tie.begin(), tie.end());
  return tie;
}

PoseMap PosesOf(const std::vector<FrameState*>& registered) {
  PoseMap poses;
  for (const FrameState* frame : registered) poses[frame->frame] = frame->cam_from_world.ToRigid();
  return poses;
}

// How far an adjustment moved the cameras where the points are seen, px:
// the median over the points' views of the distance between the point's
// projections through the cameras before and after.
double MedianShiftAtPointsPx(const PoseMap& before, const CameraModel& camera_before, const PoseMap& after,
                             const CameraModel& camera_after, const std::vector<FeaturePoint>& points) {
  std::vector<double> shifts;
  for (const FeaturePoint& p : points) {
    for (const auto& view : p.observations) {
      const Eigen::Vector3d old_cam = before.at(view.first) * p.position, new_cam = after.at(view.first) * p.position;
      if (old_cam.z() > 0 && new_cam.z() > 0) {
        shifts.push_back((camera_after.Project(new_cam) - camera_before.Project(old_cam)).norm());
      }
    }
  }
  if (shifts.empty()) return 0.0;
  const auto middle = shifts.begin() + static_cast<std::ptrdiff_t>(shifts.size() / 2);
  std::nth_element(shifts.begin(), middle, shifts.end());
  return *middle;
}

}  // namespace

void Reconstructor::TriangulateAndAdjust(const std::vector<FrameState*>& registered, const PointTriangulation& triangulate,
                                         ReconstructionResult* result) {
  PoseMap poses = PosesOf(registered);
  for (int round = 0;; ++round) {
    const CameraModel camera = camera_;
    result->feature_points = triangulate(poses, camera_);
    if (!options_.final_adjustment) return;
    AdjustWithPoints(registered, &result->feature_points, result);
    PoseMap adjusted = PosesOf(registered);
    result->points_shift_px = MedianShiftAtPointsPx(poses, camera, adjusted, camera_, result->feature_points);
    if (!(result->points_shift_px > options_.points_refit_shift_px) || round == options_.max_points_refits) return;
    ++result->points_refits;
    poses = std::move(adjusted);
  }
}

void Reconstructor::AdjustWithPoints(const std::vector<FrameState*>& registered, std::vector<FeaturePoint>* points,
                                     ReconstructionResult* result) {
  if (points->empty()) return;
  // Each kind counts by its precision: the corners' noise per axis from the
  // targets' reprojection after the final adjustment, the points' from
  // their tracks (SIFT keypoints, ~10x noisier).
  std::vector<double> point_rms;
  for (const FeaturePoint& p : *points) point_rms.push_back(p.reprojection_rms_px);
  std::nth_element(point_rms.begin(), point_rms.begin() + static_cast<long>(point_rms.size() / 2), point_rms.end());
  ReconstructionResult tags_only;
  CollectReprojectionStatistics(registered, &tags_only);
  const double corner_sigma = std::max(0.01, tags_only.reprojection_rms_px / std::sqrt(2.0));
  const double point_sigma = std::max(0.1, point_rms[point_rms.size() / 2] / std::sqrt(2.0));
  const std::vector<size_t> tie = TiePoints(*points, options_.tie_points_per_keyframe, camera_);
  std::vector<AdjustedPoint> adjusted(tie.size());
  for (size_t k = 0; k < tie.size(); ++k) {
    adjusted[k].position = (*points)[tie[k]].position;
    adjusted[k].observations = (*points)[tie[k]].observations;
  }
  PointTerms terms;
  terms.points = &adjusted;
  terms.camera = &camera_;
  terms.weight = corner_sigma / point_sigma;
  terms.huber_px = 2 * point_sigma;
  BundleAdjusterOptions options = options_.ba;
  options.square_pixels = square_pixels_;
  // The targets' covariance from this adjustment: the points' rays, which
  // moved the tags, inform their sigma too (the tags-only one is kept if
  // this one cannot be computed).
  options.compute_covariance = true;
  // 8 iterations: the points start at their triangulation, the poses at the
  // targets-only optimum; the 1280x720 box walk, box_small, wall_small and
  // box_photos give clouds within 0.1 um (median; 0.4 um at the 99th
  // percentile) of 40 iterations' in a fifth of the time.
  options.global_iterations = std::min(options.global_iterations, 8);
  const GlobalAdjustmentSummary summary = AdjustGlobally(registered, &tags_, fx_, fy_, options,
                                                         result->intrinsics_refined ? &camera_ : nullptr, &terms);
  result->points_adjusted = static_cast<int>(adjusted.size());
  result->points_adjustment_s = summary.solve_s;
  if (summary.covariance) {
    result->covariance = summary.covariance;
    result->covariance_note = summary.covariance_note;
    if (summary.intrinsics_covariance) result->intrinsics_covariance = summary.intrinsics_covariance;
  }
  result->covariance_s += summary.covariance_s;
  const PoseMap poses = PosesOf(registered);
  // The tie points where the adjustment put them, the others refined on its poses.
  std::vector<bool> in_adjustment(points->size(), false);
  for (size_t k = 0; k < tie.size(); ++k) {
    (*points)[tie[k]].position = adjusted[k].position;
    in_adjustment[tie[k]] = true;
  }
  std::vector<size_t> rest;
  for (size_t i = 0; i < points->size(); ++i) {
    if (!in_adjustment[i]) rest.push_back(i);
  }
  HeldPoseRefinementOptions held;
  held.huber_px = terms.huber_px;
  held.threads = options_.points_threads;
  const auto t0 = std::chrono::steady_clock::now();
  RefinePointsOnHeldPoses(poses, camera_, held, rest, points);
  result->points_adjustment_s += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  // Kept where the adjusted point still reprojects like a point of its kind.
  std::vector<FeaturePoint> kept;
  for (FeaturePoint& p : *points) {
    double sum = 0;
    bool in_front = true;
    for (const auto& [frame, pixel] : p.observations) {
      const Eigen::Vector3d in_cam = poses.at(frame) * p.position;
      in_front = in_front && in_cam.z() > 0;
      sum += (camera_.Project(in_cam) - pixel).squaredNorm();
    }
    const double triangulated_rms_px = p.reprojection_rms_px;
    p.reprojection_rms_px = std::sqrt(sum / static_cast<double>(p.observations.size()));
    if (in_front && p.reprojection_rms_px <= std::max(2.0 * triangulated_rms_px, 1.0)) kept.push_back(std::move(p));
  }
  *points = std::move(kept);
}

}  // namespace tagsfm
