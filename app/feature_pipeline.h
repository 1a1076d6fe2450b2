#pragma once
// The natural-feature half of the hybrid pipeline, as replay and the daemon
// run it: SIFT tracks on keyframes (frames whose registered pose has moved
// enough since the last one: SIFT costs 10-50x a tag detection, and frames
// closer together add no triangulation angle), triangulated at the end from
// the final, target-derived poses, so the points are metric.
#include <memory>
#include <optional>
#include <vector>

#include <opencv2/core.hpp>

#include "tagsfm/capture/recording.h"
#include "tagsfm/feature/feature_tracker.h"
#include "tagsfm/feature/feature_triangulation.h"
#include "tagsfm/recon/reconstructor.h"

namespace tagsfm {

struct FeaturePipelineOptions {
  FeatureTrackerOptions tracker;
  FeatureTriangulationOptions triangulation;
  double keyframe_baseline = 0.03;   // camera moved by this fraction of the distance to the tags...
  double keyframe_rotation_deg = 3;  // ...or turned by this much since the last feature keyframe
  // Larger images are scaled down to this longer side for SIFT (its cost
  // grows with the pixel count; on box_small half size was 2.5x cheaper for
  // 2.9 instead of 2.2 mm median point error). 0: never.
  int max_feature_image_side = 1280;

  Status Check() const;
};

class FeaturePipeline {
 public:
  static Result<std::unique_ptr<FeaturePipeline>> Create(const CameraModel& camera, const TargetConfig& targets,
                                                         const FeaturePipelineOptions& options);

  // Whether a frame, after reconstruction saw it, is a feature keyframe;
  // if so it is the one the next frames' motion is measured from. The
  // daemon selects live and tracks at the end, from the recording, so that
  // SIFT never holds up the live loop; replay tracks at once. Both track the
  // same frames in the same order, so their points agree.
  bool SelectKeyframe(const DetectionSet& detections, const FrameReport& report);
  // Tracks the features of the next selected keyframe. `colour`: the frame
  // as captured (8-bit BGR gives the points' colours).
  Status Track(const cv::Mat& gray, const cv::Mat& colour, const DetectionSet& detections);

  // Points from every track, with the final poses.
  std::vector<FeaturePoint> Triangulate(const PoseMap& cam_from_world, const CameraModel& camera) const;

  int keyframes() const { return static_cast<int>(sets_.size()); }

 private:
  FeaturePipeline(CameraModel camera, TargetConfig targets, FeaturePipelineOptions options,
                  std::unique_ptr<FeatureTracker> tracker);
  bool IsFarFromLastKeyframe(const DetectionSet& detections, const FrameReport& report) const;

  CameraModel camera_;
  TargetConfig targets_;
  FeaturePipelineOptions options_;
  std::unique_ptr<FeatureTracker> tracker_;
  std::optional<Rigid3d> last_keyframe_;
  std::vector<FeatureSet> sets_;
};

}  // namespace tagsfm
