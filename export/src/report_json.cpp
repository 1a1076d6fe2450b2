// report.json: the run's figures (frames, points, reprojection error,
// latencies, the camera) for people and for `tagsfm evaluate`.
#include <algorithm>
#include <cmath>
#include <map>
#include <optional>

#include <nlohmann/json.hpp>

#include "tagsfm/core/file_util.h"
#include "tagsfm/export/feature_triangulation_json.h"
#include "tagsfm/export/result_writer.h"
#include "tagsfm/recon/intrinsics_check.h"
#include "tagsfm/recon/measurement.h"
#include "tagsfm/recon/tag_geometry.h"

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

// A known map (its tags held fixed) fixes the scale itself.
bool HasKnownTags(const ReconstructionResult& result) {
  return std::any_of(result.tags.begin(), result.tags.end(), [](const auto& t) { return t.second.known; });
}

// Where the scale comes from; sigma_rel is what `measure` adds to every
// length's sigma (scale part = sigma_rel * length). With the scale from the
// tag sizes, images_sigma_rel is how well the corners fix it (already in
// every length's sigma through the covariance) and total_sigma_rel both
// together: what a surveyor quotes for the map's scale.
nlohmann::json ScaleJson(const ReconstructionResult& result) {
  const MapScale& scale = result.scale;
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
  const bool known_map = HasKnownTags(result);
  std::optional<double> images;
  if (result.covariance && !known_map && scale.source == "tag sizes") images = MapScaleSigmaRel(result.Targets(), *result.covariance);
  out["images_sigma_rel"] = images ? nlohmann::json(*images) : nlohmann::json(nullptr);
  out["total_sigma_rel"] = images ? nlohmann::json(std::hypot(*images, scale.sigma_rel)) : nlohmann::json(nullptr);
  if (!scale.note.empty()) out["note"] = scale.note;
  return out;
}

// Frames and targets: how many were read, registered, seen and mapped, and
// why the others were not.
void AddFramesAndTargets(const ReconstructionResult& result, const RunStats& stats, nlohmann::json* report) {
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
  nlohmann::json unmapped = nlohmann::json::array();
  for (const auto& [id, why] : result.unmapped_tags) unmapped.push_back({{"tag", id}, {"reason", why}});
  nlohmann::json& r = *report;
  r["frames"] = stats.frames;
  r["registered_frames"] = registered;
  r["frames_skipped"] = stats.frames_skipped;
  r["unregistered_frames"] = unregistered;
  r["skipped_frames"] = skipped;
  r["targets_seen"] = seen.size();
  r["targets_mapped"] = result.tags.size();
  r["unmapped_targets"] = unmapped;  // seen but not mapped, with why
}

// Each mapped target as a surveyor checks it: its rays (views in the
// adjustment), the views left out, its corners' reprojection RMS and its
// centre's sigma per world axis. That sigma is the final adjustment's,
// relative to the datum (the anchor tag at the origin, or a known map,
// both held fixed), plus what the images cannot see: the scale's sigma
// times the centre's distance from the anchor, as `measure` adds it to
// distances. A known map fixes the scale itself, so it adds none.
nlohmann::json TargetsJson(const ReconstructionResult& result) {
  const bool known_map = HasKnownTags(result);
  const double scale_sigma_rel = known_map ? 0.0 : result.scale.sigma_rel;
  std::map<TagId, Eigen::Vector3d> centre_sigma;
  if (result.covariance) {
    const TagCovariance& c = *result.covariance;
    for (size_t i = 0; i < c.ids.size(); ++i) {
      const auto tag = result.tags.find(c.ids[i]);
      if (tag == result.tags.end()) continue;
      const Eigen::Vector3d centre = TagCenter(tag->second.CornersInWorld());
      const Eigen::Matrix3d position = c.covariance.block<3, 3>(6 * i + 3, 6 * i + 3) +
                                       scale_sigma_rel * scale_sigma_rel * centre * centre.transpose();
      centre_sigma[c.ids[i]] = position.diagonal().cwiseMax(0.0).cwiseSqrt();
    }
  }
  nlohmann::json targets = nlohmann::json::array();
  for (const auto& [id, tag] : result.tags) {
    const auto stats = result.target_stats.find(id);
    const TargetStats s = stats == result.target_stats.end() ? TargetStats{} : stats->second;
    nlohmann::json t = {{"tag", id}, {"known", tag.known}, {"anchor", tag.anchor},
                        {"size_m", tag.size_m}, {"views", s.track_length},
                        {"outlier_views", s.outlier_views}, {"rms_px", s.rms_px}};
    if (auto sigma = centre_sigma.find(id); sigma != centre_sigma.end()) {
      const Eigen::Vector3d mm = 1e3 * sigma->second;
      t["sigma_mm"] = {mm.x(), mm.y(), mm.z()};
    } else {
      t["sigma_mm"] = nullptr;  // held fixed (known map, the anchor) or no covariance
    }
    targets.push_back(std::move(t));
  }
  return targets;
}

// Points, observations and the reprojection RMS of the target corners, the
// feature points and all observations together.
void AddPointsAndReprojection(const ReconstructionResult& result, nlohmann::json* report) {
  nlohmann::json& r = *report;
  r["points"] = 4 * result.tags.size() + result.feature_points.size();
  r["feature_points"] = result.feature_points.size();
  r["observations"] = result.observations;
  r["outlier_observations"] = result.outlier_observations;  // tag views left out of the adjustment
  r["tags_remapped"] = result.tags_remapped;                // learned tags mapped again while running
  // The corners' errors as scale^2 C + floor^2 against the detector's covariance C (weighted corners).
  r["corner_noise"] = {{"scale", result.corner_noise.scale}, {"floor_px", result.corner_noise.floor_px}};
  double sum_sq = result.reprojection_rms_px * result.reprojection_rms_px * result.observations;
  double feature_sum_sq = 0;
  size_t count = static_cast<size_t>(result.observations), feature_count = 0;
  for (const FeaturePoint& p : result.feature_points) {
    feature_sum_sq += p.reprojection_rms_px * p.reprojection_rms_px * static_cast<double>(p.observations.size());
    feature_count += p.observations.size();
  }
  sum_sq += feature_sum_sq;
  count += feature_count;
  r["reprojection_rms_px"] = count ? std::sqrt(sum_sq / static_cast<double>(count)) : 0.0;
  r["feature_reprojection_rms_px"] = feature_count ? std::sqrt(feature_sum_sq / static_cast<double>(feature_count)) : 0.0;
  r["target_reprojection_rms_px"] = result.reprojection_rms_px;
}

// The run's timings, tag search and feature stage.
void AddRunStatistics(const RunStats& stats, nlohmann::json* report) {
  nlohmann::json& r = *report;
  r["runtime_s"] = stats.runtime_s;
  r["frame_latency_ms"] = LatencyJson(stats.frame_latency_ms);
  if (!stats.detection_ms.empty()) r["detection_ms"] = LatencyJson(stats.detection_ms);
  if (!stats.tag_search.empty()) {
    r["tag_search"] = {{"mode", stats.tag_search},
                       {"full_frame_detections", stats.full_frame_detections},
                       {"recoveries", stats.tag_search_recoveries},
                       {"fine_full_frame_detections", stats.fine_full_frame_detections}};
  }
  if (!stats.feature_ms.empty()) {
    r["feature_keyframes"] = stats.feature_ms.size();
    r["feature_ms"] = LatencyJson(stats.feature_ms);
    r["triangulation_s"] = stats.triangulation_s;
    r["feature_work_dropped"] = stats.feature_work_dropped;
    r["feature_keyframes_rematched"] = stats.feature_keyframes_rematched;
    r["feature_triangulation"] = FeatureTriangulationJson(stats.feature_triangulation);
  }
  r["peak_rss_mb"] = stats.peak_rss_mb;
  r["mode"] = stats.mode;
  r["scale_kind"] = stats.mode.rfind("sfm alone", 0) == 0 ? "arbitrary" : "metric";  // targets give metres, SfM alone not
}

// The camera, and with refined intrinsics their sigma and verdict
// (recon/intrinsics_check.h).
void AddCamera(const ReconstructionResult& result, nlohmann::json* report) {
  nlohmann::json& r = *report;
  const CameraModel& c = result.camera;
  r["camera"] = {{"model", CameraModel::KindName(c.kind)}, {"width", c.width}, {"height", c.height}, {"fx", c.fx},
                 {"fy", c.fy}, {"cx", c.cx}, {"cy", c.cy}, {"distortion", c.distortion}};
  r["intrinsics_refined"] = result.intrinsics_refined;
  if (result.intrinsics_refined) r["square_pixels"] = result.square_pixels;
  if (const std::optional<IntrinsicsUncertainty> u = JudgeIntrinsics(result, {})) {
    const std::array<double, 6>& s = u->sigma;
    r["intrinsics_sigma"] = {{"fx", s[0]}, {"fy", s[1]}, {"cx", s[2]}, {"cy", s[3]}, {"k1", s[4]}, {"k2", s[5]},
                             {"observed_radius_px", u->observed_radius_px},
                             {"distortion_px", u->distortion_sigma_px},
                             {"distortion_at_corners_px", u->distortion_sigma_corner_px}};
    r["intrinsics_unconstrained"] = u->unconstrained;  // empty: the views constrain them
  }
}

// The final adjustments: convergence, times, the covariance's file or why
// there is none.
void AddAdjustment(const ReconstructionResult& result, nlohmann::json* report) {
  nlohmann::json& r = *report;
  r["pose_methods"] = result.pose_method_counts;
  r["global_adjustment_converged"] = result.global_adjustment_converged;
  r["global_adjustment_s"] = result.global_adjustment_s;
  r["covariance_s"] = result.covariance_s;
  r["points_adjusted"] = result.points_adjusted;          // feature points adjusted with the targets (the tie points)
  r["points_adjustment_s"] = result.points_adjustment_s;
  r["points_shift_px"] = result.points_shift_px;  // cameras moved at the points by the last adjustment with them
  r["points_refits"] = result.points_refits;      // times the points were triangulated again from the adjusted poses
  r["window_solves_failed"] = result.window_solves_failed;
  r["frames_thinned"] = result.frames_thinned;  // tag views given back in a long capture (recon.max_retained_frames)  // undone, see SlidingWindowBundleAdjuster::Solve
  if (result.anchor_tag) r["anchor_tag"] = *result.anchor_tag;
  r["covariance"] = result.covariance ? "targets_cov.csv" : result.covariance_note;
}

}  // namespace

Status WriteReport(const std::filesystem::path& path, const ReconstructionResult& result, const RunStats& stats) {
  nlohmann::json report;
  AddFramesAndTargets(result, stats, &report);
  report["scale"] = ScaleJson(result);
  report["targets"] = TargetsJson(result);
  AddPointsAndReprojection(result, &report);
  AddRunStatistics(stats, &report);
  AddAdjustment(result, &report);
  AddCamera(result, &report);
  return WriteFileAtomically(path, report.dump(2) + "\n");
}

}  // namespace tagsfm
