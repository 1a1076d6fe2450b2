#include "tagsfm/pipeline/feature_stage.h"

#include <algorithm>
#include <cmath>

namespace tagsfm {

Status FeatureStageOptions::Check() const {
  if (Status s = tracker.Check(); !s) return s;
  if (Status s = triangulation.Check(); !s) return s;
  if (max_feature_image_side < 0) return MakeError("features.max_feature_image_side must be >= 0");
  return Status::Ok();
}

FeatureStage::FeatureStage(CameraModel camera, TargetConfig targets, FeatureStageOptions options,
                                 std::unique_ptr<FeatureTracker> tracker)
    : camera_(std::move(camera)), targets_(std::move(targets)), options_(options), tracker_(std::move(tracker)) {}

Result<std::unique_ptr<FeatureStage>> FeatureStage::Create(const CameraModel& camera, const TargetConfig& targets,
                                                                 const FeatureStageOptions& options) {
  if (Status s = options.Check(); !s) return s.error();
  FeatureTrackerOptions tracker_options = options.tracker;
  const int side = std::max(camera.width, camera.height);
  if (options.max_feature_image_side > 0 && side > options.max_feature_image_side) {
    tracker_options.image_scale = std::min(tracker_options.image_scale, double(options.max_feature_image_side) / side);
  }
  auto tracker = FeatureTracker::Create(tracker_options);
  if (!tracker) return tracker.error();
  return std::unique_ptr<FeatureStage>(new FeatureStage(camera, targets, options, std::move(*tracker)));
}

bool FeatureStage::SelectKeyframe(const FrameReport& report) const { return report.registered && report.keyframe; }

Status FeatureStage::Track(const cv::Mat& gray, const cv::Mat& colour, const DetectionSet& detections) {
  auto set = tracker_->Track(gray, colour, detections);
  if (!set) return set.error();
  sets_.push_back(std::move(*set));
  return Status::Ok();
}

std::vector<FeaturePoint> FeatureStage::Triangulate(const PoseMap& cam_from_world, const CameraModel& camera) const {
  return TriangulateFeatureTracks(sets_, cam_from_world, camera, options_.triangulation);
}

}  // namespace tagsfm
