#include "tagsfm/feedback/live_feedback.h"

#include <cmath>
#include <algorithm>
#include <cstdio>

#include "tagsfm/recon/error_model.h"

namespace tagsfm {
namespace {

constexpr double kDegToRad = M_PI / 180.0;
constexpr size_t kMaxIdsInAWarning = 6;

std::string Millimetres(double metres) {
  char text[32];
  std::snprintf(text, sizeof text, metres < 0.01 ? "%.2f mm" : "%.1f mm", metres * 1000.0);
  return text;
}

std::string Metres(double metres) {
  char text[32];
  std::snprintf(text, sizeof text, "%.2f m", metres);
  return text;
}

std::string IdList(const std::vector<TagId>& ids) {
  std::string text;
  for (size_t i = 0; i < ids.size() && i < kMaxIdsInAWarning; ++i) text += (i ? ", " : "") + std::to_string(ids[i]);
  if (ids.size() > kMaxIdsInAWarning) text += " and " + std::to_string(ids.size() - kMaxIdsInAWarning) + " more";
  return text;
}

}  // namespace

Status LiveFeedbackOptions::Check() const {
  if (!(point_error_goal_m > 0)) return MakeError("feedback.point_error_goal_m must be > 0");
  if (!(baseline_angle_deg > 0 && baseline_angle_deg < 180)) return MakeError("feedback.baseline_angle_deg must be in (0, 180)");
  if (min_targets_in_view < 1) return MakeError("feedback.min_targets_in_view must be >= 1");
  if (min_views_per_target < 1) return MakeError("feedback.min_views_per_target must be >= 1");
  if (!(min_direction_spread_deg >= 0)) return MakeError("feedback.min_direction_spread_deg must be >= 0");
  if (!(min_image_noise_px > 0)) return MakeError("feedback.min_image_noise_px must be > 0");
  return Status::Ok();
}

LiveFeedback::LiveFeedback(CameraModel camera, TargetConfig targets, LiveFeedbackOptions options)
    : camera_(std::move(camera)), targets_(std::move(targets)), options_(options) {
  status_.image_noise_px = 0.3;  // a typical corner noise until a frame measures it
  status_.point_error_goal_m = options_.point_error_goal_m;
  status_.min_views_per_target = options_.min_views_per_target;
  status_.min_direction_spread_deg = options_.min_direction_spread_deg;
}

const LiveStatus& LiveFeedback::Update(const DetectionSet& detections, const FrameReport& report,
                                       std::int64_t timestamp_ns) {
  if (last_timestamp_ns_ >= 0 && timestamp_ns > last_timestamp_ns_) {
    const double instant = 1e9 / static_cast<double>(timestamp_ns - last_timestamp_ns_);
    // Smoothed, so the number on screen can be read.
    status_.frames_per_second = status_.frames_per_second > 0 ? 0.8 * status_.frames_per_second + 0.2 * instant : instant;
  }
  last_timestamp_ns_ = timestamp_ns;
  status_.frame = detections.frame;
  status_.registered = report.registered;
  status_.reason = report.reason;
  status_.targets_in_view = static_cast<int>(detections.tags.size());
  status_.targets_mapped = static_cast<int>(report.mapped_tags);
  if (report.registered && report.tags_used > 0) {
    // The pose's reprojection RMS underestimates the corner noise by the
    // 6 degrees of freedom it absorbed: sigma^2 = rms^2 * 2n / (2n - 6).
    const double n2 = 8.0 * report.tags_used;
    if (n2 > 6) {
      // The median of recent frames: one frame's RMS jumps with one bad corner.
      recent_noise_px_.push_back(report.rms_px * std::sqrt(n2 / (n2 - 6)));
      if (recent_noise_px_.size() > kNoiseWindow) recent_noise_px_.pop_front();
      std::vector<double> sorted(recent_noise_px_.begin(), recent_noise_px_.end());
      std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
      status_.image_noise_px = std::max(options_.min_image_noise_px, sorted[sorted.size() / 2]);
    }
  }
  const std::vector<TagSighting> views = ComputeTagViews(camera_, targets_, detections);
  coverage_.Add(detections.frame, views);
  map_.Add(report, views);
  status_.map = map_.map();
  status_.coverage.clear();
  for (const auto& [id, c] : coverage_.targets()) status_.coverage.push_back(c);
  status_.targets_seen_total = static_cast<int>(status_.coverage.size());
  Predict(views, detections);
  Warn();
  return status_;
}

void LiveFeedback::Predict(const std::vector<TagSighting>& views, const DetectionSet& detections) {
  status_.predicted_point_error_m.reset();
  status_.predicted_position_error_m.reset();
  status_.predicted_rotation_error_deg.reset();
  status_.max_depth_for_goal_m.reset();
  status_.depth_m = 0;
  if (views.empty()) return;
  double sum = 0, sum_sq = 0;
  for (const auto& v : views) {
    sum += v.distance_m;
    sum_sq += v.distance_m * v.distance_m;
  }
  const double n = static_cast<double>(views.size());
  status_.depth_m = sum / n;
  Eigen::Vector2d centroid = Eigen::Vector2d::Zero();
  int corners = 0;
  for (const auto& tag : detections.tags) {
    for (const auto& c : tag.corners) centroid += c, ++corners;
  }
  centroid /= std::max(1, corners);
  double spread_sq = 0;
  for (const auto& tag : detections.tags) {
    for (const auto& c : tag.corners) spread_sq += (c - centroid).squaredNorm();
  }
  ViewConditions view;
  view.depth_m = status_.depth_m;
  view.focal_px = 0.5 * (camera_.fx + camera_.fy);
  view.image_noise_px = status_.image_noise_px;
  view.num_targets = corners;
  view.spread_px = std::sqrt(spread_sq / std::max(1, corners));
  view.depth_relief = std::sqrt(std::max(0.0, sum_sq / n - status_.depth_m * status_.depth_m)) / status_.depth_m;
  if (!view.Check()) return;  // e.g. all corners on one spot: nothing to predict from
  const double baseline = options_.baseline_angle_deg * kDegToRad;
  if (auto pose = PredictPoseError(view)) {
    status_.predicted_position_error_m = pose->position_m;
    status_.predicted_rotation_error_deg = pose->rotation_deg;
  }
  if (auto point = PredictFeaturePointErrorRms(view, baseline)) status_.predicted_point_error_m = *point;
  if (auto depth = MaxDepthForPointError(options_.point_error_goal_m, view, baseline)) status_.max_depth_for_goal_m = *depth;
}

void LiveFeedback::Warn() {
  auto& w = status_.warnings;
  w.clear();
  if (!status_.registered) {
    w.push_back({"no_pose", "No camera pose for this frame" +
                (status_.reason.empty() ? "" : ": " + status_.reason)});
  }
  if (status_.targets_in_view < options_.min_targets_in_view) {
    w.push_back({"few_targets", "Only " + std::to_string(status_.targets_in_view) + " target" + (status_.targets_in_view == 1 ? "" : "s") +
                " in view: need " + std::to_string(options_.min_targets_in_view - status_.targets_in_view) +
                " more; turn the camera towards more targets"});
  }
  if (status_.max_depth_for_goal_m && status_.predicted_point_error_m &&
      status_.depth_m > *status_.max_depth_for_goal_m) {
    w.push_back({"move_closer", "Move closer: at " + Metres(status_.depth_m) + " points are off by about " +
                Millimetres(*status_.predicted_point_error_m) + "; closer than " + Metres(*status_.max_depth_for_goal_m) +
                " keeps them within " + Millimetres(options_.point_error_goal_m)});
  }
  if (status_.image_noise_px > 1.0) {
    char text[160];
    std::snprintf(text, sizeof text,
                  "Target corners are noisy (%.2f px): check focus, motion blur and light", status_.image_noise_px);
    w.push_back({"noisy_corners", text});
  }
  std::vector<TagId> few_views, one_direction;
  for (const auto& c : status_.coverage) {
    if (c.times_seen < options_.min_views_per_target) {
      few_views.push_back(c.id);
    } else if (c.direction_spread_deg < options_.min_direction_spread_deg) {
      one_direction.push_back(c.id);
    }
  }
  if (!few_views.empty()) {
    w.push_back({"few_views", "Seen fewer than " + std::to_string(options_.min_views_per_target) + " times: target" +
                (few_views.size() == 1 ? " " : "s ") + IdList(few_views)});
  }
  if (!one_direction.empty()) {
    char angle[16];
    std::snprintf(angle, sizeof angle, "%.0f", options_.min_direction_spread_deg);
    w.push_back({"one_direction", "Seen from one direction only: target" + std::string(one_direction.size() == 1 ? " " : "s ") +
                IdList(one_direction) + "; view " + (one_direction.size() == 1 ? "it" : "them") +
                " from at least " + angle + " degrees further to the side"});
  }
}

}  // namespace tagsfm
