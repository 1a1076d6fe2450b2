#pragma once
// What the operator sees while capturing: per frame, whether it registered,
// how far the camera is from the targets and what error that distance causes
// at the current image noise, the target coverage so far, and warnings in
// plain words ("move closer than 1.8 m", "need 3 more targets in view").
#include <deque>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "tagsfm/feedback/coverage.h"
#include "tagsfm/feedback/live_map.h"
#include "tagsfm/recon/reconstructor.h"

namespace tagsfm {

struct LiveFeedbackOptions {
  double point_error_goal_m = 0.001;  // RMS accuracy the operator wants for feature points
  double baseline_angle_deg = 15.0;   // typical angle between views of a point while walking round
  int min_targets_in_view = 4;        // fewer: the pose is weak or impossible
  int min_views_per_target = 3;
  double min_direction_spread_deg = 20.0;  // a target's views should differ by this much
  double min_image_noise_px = 0.05;   // floor of the noise estimate (corner RMS of a single frame is optimistic)

  Status Check() const;
};

// A warning in plain words, and what kind of warning it is, so that a
// terminal can say it once rather than each time its numbers change.
struct LiveWarning {
  std::string kind;  // "no_pose", "few_targets", "move_closer", "noisy_corners", "few_views", "one_direction"
  std::string text;
};

struct LiveStatus {
  FrameId frame = 0;
  double frames_per_second = 0;
  bool registered = false;
  std::string reason;                 // why not registered
  int targets_in_view = 0;
  int targets_mapped = 0;
  int targets_seen_total = 0;
  double depth_m = 0;                 // mean camera-to-target distance in this frame
  double image_noise_px = 0;          // estimated corner noise (from the frame's reprojection RMS)
  std::optional<double> predicted_point_error_m;     // feature point RMS error at this depth and noise
  std::optional<double> predicted_position_error_m;  // camera centre RMS error
  std::optional<double> predicted_rotation_error_deg;
  std::optional<double> max_depth_for_goal_m;        // closer than this meets point_error_goal_m
  std::vector<TargetCoverage> coverage;              // every target seen so far, by id
  LiveMap map;                                       // the dashboard's top view
  // The goals the warnings use, so that a display can colour by them.
  double point_error_goal_m = 0;
  int min_views_per_target = 0;
  double min_direction_spread_deg = 0;
  std::vector<LiveWarning> warnings;                 // most important first

  // The live cloud (pipeline/feature_stage.h), filled by the pipeline.
  int feature_points = 0;                            // feature points triangulated so far
  std::vector<Eigen::Vector3f> cloud_sample;         // at most 2000 of them, world frame, metres
  int feature_keyframes = 0;                         // keyframes in the feature map so far
  int feature_work_dropped = 0;                      // keyframes whose feature work was dropped live
};

class LiveFeedback {
 public:
  LiveFeedback(CameraModel camera, TargetConfig targets, LiveFeedbackOptions options);

  // One frame: its detections and what reconstruction made of it.
  const LiveStatus& Update(const DetectionSet& detections, const FrameReport& report, std::int64_t timestamp_ns);
  const LiveStatus& status() const { return status_; }

 private:
  void Predict(const std::vector<TagSighting>& views, const DetectionSet& detections);
  void Warn();

  CameraModel camera_;
  TargetConfig targets_;
  LiveFeedbackOptions options_;
  CoverageTracker coverage_;
  LiveMapTracker map_;
  LiveStatus status_;
  std::int64_t last_timestamp_ns_ = -1;
  static constexpr size_t kNoiseWindow = 15;
  std::deque<double> recent_noise_px_;
};

std::string LiveStatusJson(const LiveStatus& status);

}  // namespace tagsfm
