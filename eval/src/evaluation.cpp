// The comparison itself, on loaded values (see evaluation.h).
#include "tagsfm/eval/evaluation.h"

#include <algorithm>
#include <cmath>

namespace tagsfm::eval {
namespace {

// A result's frame carried into the true frame by `true_from_est`.
PoseErrors ComparePoses(const EvaluationInput& in, const Sim3d& true_from_est) {
  PoseErrors errors;
  std::vector<double> reprojection, rotation_rel, rotation_deg, position;
  for (const auto& [frame, true_pose] : *in.true_poses) {
    const auto it = in.estimated_poses->find(frame);
    if (it == in.estimated_poses->end()) continue;
    const Rigid3d estimated = true_from_est.TransformPose(it->second);
    FrameError e;
    e.frame = frame;
    // Eq. 2 with the quaternions on the same hemisphere (q and -q are one rotation).
    Eigen::Vector4d q_est = estimated.rotation.coeffs();
    const Eigen::Vector4d q_true = true_pose.rotation.coeffs();
    if (q_est.dot(q_true) < 0) q_est = -q_est;
    e.rotation_rel = (q_est - q_true).norm() / q_true.norm();
    e.rotation_deg = RotationAngleDeg(estimated.rotation, true_pose.rotation);
    e.position_m = (estimated.Center() - true_pose.Center()).norm();  // eq. 3
    if (in.camera && in.true_targets) {
      // Eq. 1 over the true corners the true camera sees.
      double sum = 0;
      int n = 0;
      for (const auto& [id, corners] : *in.true_targets) {
        for (const Eigen::Vector3d& corner : corners) {
          const Eigen::Vector3d in_true_cam = true_pose * corner, in_est_cam = estimated * corner;
          if (in_true_cam.z() <= 0 || in_est_cam.z() <= 0) continue;
          const Eigen::Vector2d seen = in.camera->Project(in_true_cam);
          if (seen.x() < -0.5 || seen.y() < -0.5 || seen.x() > in.camera->width - 0.5 ||
              seen.y() > in.camera->height - 0.5) {
            continue;
          }
          sum += (in.camera->Project(in_est_cam) - seen).norm();
          ++n;
        }
      }
      if (n > 0) {
        e.reprojection_px = sum / n;
        reprojection.push_back(*e.reprojection_px);
      }
    }
    rotation_rel.push_back(e.rotation_rel);
    rotation_deg.push_back(e.rotation_deg);
    position.push_back(e.position_m);
    errors.frames.push_back(e);
  }
  errors.reprojection_px = Stats::Of(reprojection);
  errors.rotation_rel = Stats::Of(rotation_rel);
  errors.rotation_deg = Stats::Of(rotation_deg);
  errors.position_m = Stats::Of(position);
  return errors;
}

TargetErrors CompareTargets(const EvaluationInput& in, const Sim3d& true_from_est) {
  TargetErrors errors;
  std::vector<double> distances;
  for (const auto& [id, corners] : *in.estimated_targets) {
    const auto it = in.true_targets->find(id);
    if (it == in.true_targets->end()) continue;
    ++errors.common_tags;
    for (size_t c = 0; c < 4; ++c) distances.push_back((true_from_est * corners[c] - it->second[c]).norm());
  }
  errors.corner_error_m = Stats::Of(distances);
  return errors;
}

Stats CompareCloud(const EvaluationInput& in, const Sim3d& true_from_est) {
  std::vector<double> distances;
  distances.reserve(in.cloud->size());
  for (const Eigen::Vector3d& point : *in.cloud) distances.push_back(DistanceToSurfaces(*in.surfaces, true_from_est * point));
  return Stats::Of(distances);
}

SurfaceShares CompareFeaturePoints(const EvaluationInput& in, const Sim3d& true_from_est) {
  SurfaceShares shares;
  std::vector<double> distances;
  distances.reserve(in.feature_points->size());
  int within[3] = {0, 0, 0};
  const double limits[3] = {0.001, 0.002, 0.005};
  for (const ScoredPoint& point : *in.feature_points) {
    const double d = DistanceToSurfaces(*in.surfaces, true_from_est * point.position);
    distances.push_back(d);
    for (int k = 0; k < 3; ++k) within[k] += d <= limits[k] ? 1 : 0;
  }
  const double n = static_cast<double>(distances.size());
  shares.within_1mm = within[0] / n;
  shares.within_2mm = within[1] / n;
  shares.within_5mm = within[2] / n;
  shares.distance_m = Stats::Of(std::move(distances));
  return shares;
}

AlignedErrors CompareAll(const EvaluationInput& in, const std::string& name, const Sim3d& true_from_est) {
  AlignedErrors out;
  out.name = name;
  out.true_from_est = true_from_est;
  if (in.true_poses && in.estimated_poses) out.poses = ComparePoses(in, true_from_est);
  if (in.true_targets && in.estimated_targets) out.targets = CompareTargets(in, true_from_est);
  if (in.surfaces && in.cloud) out.cloud_distance_m = CompareCloud(in, true_from_est);
  if (in.surfaces && in.feature_points && !in.feature_points->empty()) {
    out.feature_points = CompareFeaturePoints(in, true_from_est);
  }
  return out;
}

// Correspondences for the alignment: the target corners when at least two
// tags are common (their corners are exact and well spread), else the
// camera centres of the registered frames.
std::string AlignmentPoints(const EvaluationInput& in, std::vector<Eigen::Vector3d>* est,
                            std::vector<Eigen::Vector3d>* truth) {
  if (in.true_targets && in.estimated_targets) {
    for (const auto& [id, corners] : *in.estimated_targets) {
      const auto it = in.true_targets->find(id);
      if (it == in.true_targets->end()) continue;
      for (size_t c = 0; c < 4; ++c) {
        est->push_back(corners[c]);
        truth->push_back(it->second[c]);
      }
    }
    if (est->size() >= 8) return "target_corners";
    est->clear();
    truth->clear();
  }
  if (in.true_poses && in.estimated_poses) {
    for (const auto& [frame, pose] : *in.estimated_poses) {
      const auto it = in.true_poses->find(frame);
      if (it == in.true_poses->end()) continue;
      est->push_back(pose.Center());
      truth->push_back(it->second.Center());
    }
    if (est->size() >= 3) return "camera_centres";
  }
  est->clear();
  truth->clear();
  return "none";
}

// The rigid and similarity variants' corner RMS against the size of the
// scene the common targets span.
std::optional<MapPrecision> MapPrecisionOf(const std::vector<AlignedErrors>& variants,
                                           const std::vector<Eigen::Vector3d>& true_corners) {
  MapPrecision map;
  Eigen::Vector3d low = true_corners.front(), high = true_corners.front();
  for (const Eigen::Vector3d& p : true_corners) {
    low = low.cwiseMin(p);
    high = high.cwiseMax(p);
  }
  map.scene_size_m = (high - low).norm();
  bool rigid = false, similarity = false;
  for (const AlignedErrors& v : variants) {
    if (!v.targets) continue;
    const double rms = v.targets->corner_error_m.rms;
    const double ratio = rms > 0 ? map.scene_size_m / rms : 0.0;
    if (v.name == "rigid") {
      map.rigid_rms_m = rms;
      map.rigid_ratio = ratio;
      rigid = true;
    } else if (v.name == "similarity") {
      map.similarity_rms_m = rms;
      map.similarity_ratio = ratio;
      map.scale_error_ppm = (v.true_from_est.scale - 1.0) * 1e6;
      similarity = true;
    }
  }
  if (!rigid || !similarity) return std::nullopt;
  return map;
}

}  // namespace

Stats Stats::Of(std::vector<double> values) {
  Stats s;
  s.count = static_cast<int>(values.size());
  if (values.empty()) return s;
  std::sort(values.begin(), values.end());
  double sum = 0, sum_sq = 0;
  for (double v : values) {
    sum += v;
    sum_sq += v * v;
  }
  const size_t n = values.size();
  s.mean = sum / n;
  s.rms = std::sqrt(sum_sq / n);
  s.median = n % 2 ? values[n / 2] : 0.5 * (values[n / 2 - 1] + values[n / 2]);
  // Nearest-rank percentile.
  s.p95 = values[std::min(n - 1, static_cast<size_t>(std::ceil(0.95 * n)) - 1)];
  s.max = values.back();
  return s;
}

Evaluation Evaluate(const EvaluationInput& in) {
  Evaluation e;
  if (in.true_poses) {
    e.ground_truth_frames = static_cast<int>(in.true_poses->size());
    for (const auto& [frame, pose] : *in.true_poses) {
      if (in.estimated_poses && in.estimated_poses->count(frame)) ++e.registered_frames;
    }
    e.unregistered_frames = e.ground_truth_frames - e.registered_frames;
    if (in.estimated_poses) {
      for (const auto& [frame, pose] : *in.estimated_poses) e.unknown_frames += in.true_poses->count(frame) ? 0 : 1;
    }
  }
  if (in.true_targets && in.estimated_targets) {
    for (const auto& [id, c] : *in.true_targets) {
      if (!in.estimated_targets->count(id)) e.missing_tags.push_back(id);
    }
    for (const auto& [id, c] : *in.estimated_targets) {
      if (!in.true_targets->count(id)) e.unknown_tags.push_back(id);
    }
  }
  if (in.cloud) e.cloud_points = static_cast<int>(in.cloud->size());
  if (in.feature_points && !in.feature_points->empty()) {
    e.feature_points = static_cast<int>(in.feature_points->size());
    double sum = 0;
    for (const ScoredPoint& p : *in.feature_points) sum += p.reprojection_px;
    e.feature_mean_reprojection_px = sum / e.feature_points;
  }

  e.variants.push_back(CompareAll(in, "as_is", Sim3d()));
  std::vector<Eigen::Vector3d> est, truth;
  e.alignment_source = AlignmentPoints(in, &est, &truth);
  e.alignment_correspondences = static_cast<int>(est.size());
  if (e.alignment_source != "none") {
    for (const bool with_scale : {false, true}) {
      Result<Sim3d> sim = EstimateSim3d(est, truth, with_scale);
      if (sim) e.variants.push_back(CompareAll(in, with_scale ? "similarity" : "rigid", *sim));
    }
  }
  if (e.alignment_source == "target_corners") e.map = MapPrecisionOf(e.variants, truth);
  if (in.true_targets && in.estimated_targets) {
    e.lengths = CompareLengths(*in.true_targets, *in.estimated_targets, in.target_covariance, in.scale_sigma_rel);
    if (e.lengths->pairs.empty()) e.lengths.reset();
  }
  return e;
}

}  // namespace tagsfm::eval
