#include "tagsfm/pipeline/feature_stage.h"

#include <algorithm>
#include <cmath>

namespace tagsfm {

Status FeatureStageOptions::Check() const {
  if (Status s = tracker.Check(); !s) return s;
  if (Status s = triangulation.Check(); !s) return s;
  if (!(keyframe_baseline >= 0)) return MakeError("features.keyframe_baseline must be >= 0");
  if (!(keyframe_rotation_deg >= 0)) return MakeError("features.keyframe_rotation_deg must be >= 0");
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

bool FeatureStage::SelectKeyframe(const DetectionSet& detections, const FrameReport& report) {
  if (!report.registered) return false;
  if (!last_keyframe_ || IsFarFromLastKeyframe(detections, report)) {
    last_keyframe_ = report.cam_from_world;
    return true;
  }
  return false;
}

bool FeatureStage::IsFarFromLastKeyframe(const DetectionSet& detections, const FrameReport& report) const {
  if (RotationAngleDeg(report.cam_from_world.rotation, last_keyframe_->rotation) >= options_.keyframe_rotation_deg) return true;
  // Distance to the tags from their apparent size (median over the tags in
  // view): f * size / side.
  std::vector<double> depths;
  for (const TagDetection& tag : detections.tags) {
    double side = 0;
    for (int k = 0; k < 4; ++k) side += (tag.corners[static_cast<size_t>(k)] - tag.corners[static_cast<size_t>((k + 1) % 4)]).norm() / 4;
    if (side > 1) depths.push_back(camera_.fx * targets_.SizeOf(tag.id) / side);
  }
  if (depths.empty()) return false;
  std::nth_element(depths.begin(), depths.begin() + static_cast<long>(depths.size() / 2), depths.end());
  const double moved = (report.cam_from_world.Center() - last_keyframe_->Center()).norm();
  return moved >= options_.keyframe_baseline * depths[depths.size() / 2];
}

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
