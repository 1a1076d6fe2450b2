#include <cmath>

#include <nlohmann/json.hpp>

#include "tagsfm/feedback/live_feedback.h"

namespace tagsfm {
namespace {

// A tenth of a millimetre is finer than any screen shows and keeps each
// status a few kilobytes (the page gets up to 30 a second).
nlohmann::json Xyz(const Eigen::Vector3d& p) {
  const auto r = [](double v) { return std::round(v * 1e4) / 1e4; };
  return nlohmann::json::array({r(p.x()), r(p.y()), r(p.z())});
}

nlohmann::json LiveMapJson(const LiveMap& map) {
  nlohmann::json j;
  j["targets"] = nlohmann::json::array();
  for (const auto& t : map.targets) j["targets"].push_back({{"id", t.id}, {"xyz", Xyz(t.centre_in_world)}});
  j["camera"] = map.camera_in_world ? Xyz(*map.camera_in_world) : nlohmann::json(nullptr);
  j["camera_axis"] = map.camera_axis_in_world ? Xyz(*map.camera_axis_in_world) : nlohmann::json(nullptr);
  j["path"] = nlohmann::json::array();
  for (const auto& p : map.camera_path) j["path"].push_back(Xyz(p));
  j["top_x"] = Xyz(map.top_x);
  j["top_y"] = Xyz(map.top_y);
  return j;
}

}  // namespace

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
  j["map"] = LiveMapJson(s.map);
  j["goals"] = {{"point_error_m", s.point_error_goal_m},
                {"min_views_per_target", s.min_views_per_target},
                {"min_direction_spread_deg", s.min_direction_spread_deg}};
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
