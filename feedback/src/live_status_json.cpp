#include <nlohmann/json.hpp>

#include "tagsfm/feedback/live_feedback.h"

namespace tagsfm {

std::string LiveStatusJson(const LiveStatus& s) {
  nlohmann::json j;
  j["frame"] = s.frame;
  j["frames_per_second"] = s.frames_per_second;
  j["registered"] = s.registered;
  j["reason"] = s.reason;
  j["targets_in_view"] = s.targets_in_view;
  j["targets_mapped"] = s.targets_mapped;
  j["targets_seen_total"] = s.targets_seen_total;
  j["depth_m"] = s.depth_m;
  j["image_noise_px"] = s.image_noise_px;
  const auto optional = [](const std::optional<double>& v) { return v ? nlohmann::json(*v) : nlohmann::json(nullptr); };
  j["predicted_point_error_m"] = optional(s.predicted_point_error_m);
  j["predicted_position_error_m"] = optional(s.predicted_position_error_m);
  j["predicted_rotation_error_deg"] = optional(s.predicted_rotation_error_deg);
  j["max_depth_for_goal_m"] = optional(s.max_depth_for_goal_m);
  nlohmann::json coverage = nlohmann::json::array();
  for (const auto& c : s.coverage) {
    coverage.push_back({{"id", c.id},
                        {"times_seen", c.times_seen},
                        {"last_seen", c.last_seen},
                        {"min_tilt_deg", c.min_tilt_deg},
                        {"max_tilt_deg", c.max_tilt_deg},
                        {"direction_spread_deg", c.direction_spread_deg},
                        {"sectors_covered", c.SectorsCovered()},
                        {"last_distance_m", c.last_distance_m}});
  }
  j["coverage"] = coverage;
  nlohmann::json warnings = nlohmann::json::array();
  for (const auto& w : s.warnings) warnings.push_back(w.text);
  j["warnings"] = warnings;
  nlohmann::json kinds = nlohmann::json::array();
  for (const auto& w : s.warnings) kinds.push_back(w.kind);
  j["warning_kinds"] = kinds;
  j["feature_points"] = s.feature_points;
  nlohmann::json cloud = nlohmann::json::array();
  for (const Eigen::Vector3f& p : s.cloud_sample) cloud.push_back({p.x(), p.y(), p.z()});
  j["cloud"] = std::move(cloud);
  j["feature_keyframes"] = s.feature_keyframes;
  j["feature_work_dropped"] = s.feature_work_dropped;
  return j.dump();
}

}  // namespace tagsfm
