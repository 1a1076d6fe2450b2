// report.json: the run's figures (frames, points, reprojection error,
// latencies, the camera) for people and for `tagsfm evaluate`.
#include <algorithm>
#include <cmath>

#include <nlohmann/json.hpp>

#include "tagsfm/core/file_util.h"
#include "tagsfm/export/feature_triangulation_json.h"
#include "tagsfm/export/result_writer.h"
#include "tagsfm/recon/intrinsics_check.h"

namespace tagsfm {
namespace {

double Percentile(std::vector<double> values, double q) {
  if (values.empty()) return 0;
  std::sort(values.begin(), values.end());
  const size_t index = std::min(values.size() - 1, static_cast<size_t>(std::ceil(q * values.size())) - (q > 0 ? 1 : 0));
  return values[index];
}

nlohmann::json LatencyJson(const std::vector<double>& ms) {
  return {{"p50", Percentile(ms, 0.5)}, {"p95", Percentile(ms, 0.95)},
          {"max", ms.empty() ? 0.0 : *std::max_element(ms.begin(), ms.end())}};
}


std::string PointText(const ScaleBarPoint& p) {
  return p.corner < 0 ? std::to_string(p.tag) : std::to_string(p.tag) + ":" + std::to_string(p.corner);
}

// Where the scale comes from; sigma_rel is what `measure` adds to every
// length's sigma (scale part = sigma_rel * length).
nlohmann::json ScaleJson(const MapScale& scale) {
  nlohmann::json bars = nlohmann::json::array();
  for (const ScaleBarCheck& c : scale.bars) {
    bars.push_back({{"a", PointText(c.bar.a)},
                    {"b", PointText(c.bar.b)},
                    {"certified_m", c.bar.length_m},
                    {"certified_sigma_m", c.bar.sigma_m},
                    {"measured_unscaled_m", c.measured_m},
                    {"map_sigma_m", c.sigma_m},
                    {"residual_m", c.residual_m}});
  }
  nlohmann::json out = {{"source", scale.source},
                        {"factor", scale.scale},
                        {"sigma_rel", scale.sigma_rel},
                        {"scale_bars", bars}};
  if (!scale.note.empty()) out["note"] = scale.note;
  return out;
}

}  // namespace

Status WriteReport(const std::filesystem::path& path, const ReconstructionResult& result, const RunStats& stats) {
  nlohmann::json report;
  int registered = 0;
  std::map<TagId, bool> seen;
  nlohmann::json unregistered = nlohmann::json::array();
  for (const auto& f : result.frames) {
    for (const auto& obs : f.tags) seen[obs.id] = true;
    if (f.registered) {
      ++registered;
    } else {
      unregistered.push_back({{"frame", f.frame}, {"reason", f.reason}});
    }
  }
  nlohmann::json skipped = nlohmann::json::array();
  for (const auto& [frame, why] : stats.skipped) skipped.push_back({{"frame", frame}, {"reason", why}});
  report["frames"] = stats.frames;
  report["registered_frames"] = registered;
  report["frames_skipped"] = stats.frames_skipped;
  report["targets_seen"] = seen.size();
  report["targets_mapped"] = result.tags.size();
  nlohmann::json unmapped = nlohmann::json::array();
  for (const auto& [id, why] : result.unmapped_tags) unmapped.push_back({{"tag", id}, {"reason", why}});
  report["unmapped_targets"] = unmapped;  // seen but not mapped, with why
  report["scale"] = ScaleJson(result.scale);
  report["points"] = 4 * result.tags.size() + result.feature_points.size();
  report["feature_points"] = result.feature_points.size();
  report["observations"] = result.observations;
  report["outlier_observations"] = result.outlier_observations;  // tag views left out of the adjustment
  report["tags_remapped"] = result.tags_remapped;                // learned tags mapped again while running
  // All observations: target corners and feature points together.
  double sum_sq = result.reprojection_rms_px * result.reprojection_rms_px * result.observations;
  double feature_sum_sq = 0;
  size_t count = static_cast<size_t>(result.observations), feature_count = 0;
  for (const FeaturePoint& p : result.feature_points) {
    feature_sum_sq += p.reprojection_rms_px * p.reprojection_rms_px * static_cast<double>(p.observations.size());
    feature_count += p.observations.size();
  }
  sum_sq += feature_sum_sq;
  count += feature_count;
  report["reprojection_rms_px"] = count ? std::sqrt(sum_sq / static_cast<double>(count)) : 0.0;
  report["feature_reprojection_rms_px"] = feature_count ? std::sqrt(feature_sum_sq / static_cast<double>(feature_count)) : 0.0;
  report["target_reprojection_rms_px"] = result.reprojection_rms_px;
  report["runtime_s"] = stats.runtime_s;
  report["frame_latency_ms"] = LatencyJson(stats.frame_latency_ms);
  if (!stats.detection_ms.empty()) report["detection_ms"] = LatencyJson(stats.detection_ms);
  if (!stats.tag_search.empty()) {
    report["tag_search"] = {{"mode", stats.tag_search},
                            {"full_frame_detections", stats.full_frame_detections},
                            {"recoveries", stats.tag_search_recoveries},
                            {"fine_full_frame_detections", stats.fine_full_frame_detections}};
  }
  if (!stats.feature_ms.empty()) {
    report["feature_keyframes"] = stats.feature_ms.size();
    report["feature_ms"] = LatencyJson(stats.feature_ms);
    report["triangulation_s"] = stats.triangulation_s;
    report["feature_work_dropped"] = stats.feature_work_dropped;
    report["feature_keyframes_rematched"] = stats.feature_keyframes_rematched;
    report["feature_triangulation"] = FeatureTriangulationJson(stats.feature_triangulation);
  }
  report["peak_rss_mb"] = stats.peak_rss_mb;
  report["mode"] = stats.mode;
  report["scale_kind"] = stats.mode.rfind("sfm alone", 0) == 0 ? "arbitrary" : "metric";  // targets give metres, SfM alone not
  report["pose_methods"] = result.pose_method_counts;
  report["unregistered_frames"] = unregistered;
  report["skipped_frames"] = skipped;
  report["global_adjustment_converged"] = result.global_adjustment_converged;
  report["intrinsics_refined"] = result.intrinsics_refined;
  if (result.intrinsics_refined) report["square_pixels"] = result.square_pixels;
  if (const std::optional<IntrinsicsUncertainty> u = JudgeIntrinsics(result, {})) {
    const std::array<double, 6>& s = u->sigma;
    report["intrinsics_sigma"] = {{"fx", s[0]}, {"fy", s[1]}, {"cx", s[2]}, {"cy", s[3]}, {"k1", s[4]}, {"k2", s[5]},
                                  {"observed_radius_px", u->observed_radius_px},
                                  {"distortion_px", u->distortion_sigma_px},
                                  {"distortion_at_corners_px", u->distortion_sigma_corner_px}};
    report["intrinsics_unconstrained"] = u->unconstrained;  // empty: the views constrain them
  }
  report["global_adjustment_s"] = result.global_adjustment_s;
  report["covariance_s"] = result.covariance_s;
  report["points_adjusted"] = result.points_adjusted;          // feature points adjusted with the targets
  report["points_adjustment_s"] = result.points_adjustment_s;
  report["window_solves_failed"] = result.window_solves_failed;  // undone, see SlidingWindowBundleAdjuster::Solve
  if (result.anchor_tag) report["anchor_tag"] = *result.anchor_tag;
  report["covariance"] = result.covariance ? "targets_cov.csv" : result.covariance_note;
  report["camera"] = {{"model", CameraModel::KindName(result.camera.kind)}, {"width", result.camera.width},
                      {"height", result.camera.height}, {"fx", result.camera.fx}, {"fy", result.camera.fy},
                      {"cx", result.camera.cx}, {"cy", result.camera.cy}, {"distortion", result.camera.distortion}};
  return WriteFileAtomically(path, report.dump(2) + "\n");
}

}  // namespace tagsfm
