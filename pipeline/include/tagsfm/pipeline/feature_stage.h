#pragma once
// The natural-feature half of the hybrid pipeline: SIFT tracks on the
// reconstruction's own keyframes (one keyframe rule: a frame that moved 5 %
// of the tags' depth, turned 5 degrees or mapped a new tag; SIFT costs
// 10-50x a tag detection, and frames closer together add no triangulation
// angle), triangulated at the end from the final, target-derived poses, so
// the points are metric, and adjusted with the targets (Reconstructor::Finish).
#include <memory>
#include <optional>
#include <vector>

#include <opencv2/core.hpp>

#include "tagsfm/capture/recording.h"
#include "tagsfm/feature/feature_tracker.h"
#include "tagsfm/feature/feature_triangulation.h"
#include "tagsfm/recon/reconstructor.h"

namespace tagsfm {

struct FeatureStageOptions {
  bool enabled = true;  // false: targets only (photogrammetry alone)
  // Track the keyframes at Finish, from the recording, instead of at once:
  // the live loop then never waits for SIFT. Same frames, same order, same
  // points.
  bool defer = false;
  FeatureTrackerOptions tracker;
  FeatureTriangulationOptions triangulation;
  // Larger images are scaled down to this longer side for SIFT (its cost
  // grows with the pixel count; on box_small half size was 2.5x cheaper for
  // 2.9 instead of 2.2 mm median point error). 0: never.
  int max_feature_image_side = 1280;

  Status Check() const;
};

class FeatureStage {
 public:
  static Result<std::unique_ptr<FeatureStage>> Create(const CameraModel& camera, const TargetConfig& targets,
                                                         const FeatureStageOptions& options);

  // Whether a frame is a feature keyframe: a registered keyframe of the reconstruction.
  bool SelectKeyframe(const FrameReport& report) const;
  // Tracks the features of the next selected keyframe. `colour`: the frame
  // as captured (8-bit BGR gives the points' colours).
  Status Track(const cv::Mat& gray, const cv::Mat& colour, const DetectionSet& detections);

  // Points from every track, with the final poses.
  std::vector<FeaturePoint> Triangulate(const PoseMap& cam_from_world, const CameraModel& camera) const;

  int keyframes() const { return static_cast<int>(sets_.size()); }

 private:
  FeatureStage(CameraModel camera, TargetConfig targets, FeatureStageOptions options,
                  std::unique_ptr<FeatureTracker> tracker);

  CameraModel camera_;
  TargetConfig targets_;
  FeatureStageOptions options_;
  std::unique_ptr<FeatureTracker> tracker_;
  std::vector<FeatureSet> sets_;
};

}  // namespace tagsfm
