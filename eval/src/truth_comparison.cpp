#include "tagsfm/eval/truth_comparison.h"

#include <algorithm>
#include <cmath>

#include "tagsfm/eval/similarity.h"

namespace tagsfm::eval {
namespace {

double Median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

}  // namespace

TruthComparison CompareWithTruth(const PoseMap& poses, const TargetCornerMap& targets, const PoseMap& true_poses,
                                 const TargetCornerMap& true_targets, bool align_world) {
  TruthComparison out;
  std::vector<Eigen::Vector3d> estimate, truth;
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e300), hi = -lo;
  for (const auto& [id, corners] : true_targets) {
    for (const auto& c : corners) {
      lo = lo.cwiseMin(c);
      hi = hi.cwiseMax(c);
    }
    auto it = targets.find(id);
    if (it == targets.end()) continue;
    ++out.targets_compared;
    for (int k = 0; k < 4; ++k) {
      estimate.push_back(it->second[k]);
      truth.push_back(corners[k]);
    }
  }
  out.scene_size_m = true_targets.empty() ? 0 : (hi - lo).norm();
  Rigid3d truth_from_estimate;
  // Tag corners are never collinear, so the fits fail only on fewer than 3.
  const Result<Sim3d> rigid = EstimateSim3d(estimate, truth, false);
  if (rigid) {
    out.scale = EstimateSim3d(estimate, truth, true)->scale;
    if (align_world) truth_from_estimate = Rigid3d(rigid->rotation, rigid->translation);
    double sum = 0;
    for (size_t i = 0; i < estimate.size(); ++i) sum += (truth_from_estimate * estimate[i] - truth[i]).squaredNorm();
    out.corner_rms_m = std::sqrt(sum / static_cast<double>(estimate.size()));
  }
  std::vector<double> rotation, centre;
  out.frames_in_truth = static_cast<int>(true_poses.size());
  for (const auto& [frame, true_cam_from_world] : true_poses) {
    auto it = poses.find(frame);
    if (it == poses.end()) continue;
    // cam_from_truth = cam_from_estimate * estimate_from_truth
    const Rigid3d cam_from_truth = it->second * truth_from_estimate.Inverse();
    rotation.push_back(RotationAngleDeg(cam_from_truth.rotation, true_cam_from_world.rotation));
    centre.push_back((cam_from_truth.Center() - true_cam_from_world.Center()).norm());
  }
  out.frames_compared = static_cast<int>(rotation.size());
  if (!rotation.empty()) {
    out.rotation_median_deg = Median(rotation);
    out.rotation_max_deg = *std::max_element(rotation.begin(), rotation.end());
    out.centre_median_m = Median(centre);
    out.centre_max_m = *std::max_element(centre.begin(), centre.end());
  }
  return out;
}

}  // namespace tagsfm::eval
