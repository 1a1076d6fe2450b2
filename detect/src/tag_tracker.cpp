#include "tagsfm/detect/tag_tracker.h"

#include <algorithm>
#include <cmath>
#include <set>
#include <vector>

namespace tagsfm {

Status TagTrackerOptions::Check() const {
  if (full_frame_every < 1) return MakeError("full_frame_every must be >= 1 (got " + std::to_string(full_frame_every) + ")");
  if (!(padding_px >= 0.0)) return MakeError("padding_px must be >= 0");
  if (!(padding_fraction >= 0.0)) return MakeError("padding_fraction must be >= 0");
  if (!(region_quad_decimate >= 1.0f)) return MakeError("region_quad_decimate must be >= 1");
  return Status::Ok();
}

TagTracker::TagTracker(TagTrackerOptions options, std::unique_ptr<TagDetector> full,
                       std::unique_ptr<TagDetector> region)
    : options_(options), full_detector_(std::move(full)), region_detector_(std::move(region)) {}

Result<std::unique_ptr<TagTracker>> TagTracker::Create(const TagDetectorOptions& detector,
                                                       const TagTrackerOptions& tracker) {
  if (Status status = tracker.Check(); !status) return status.error();
  auto full = TagDetector::Create(detector);
  if (!full) return full.error();
  TagDetectorOptions region_options = detector;
  region_options.quad_decimate = tracker.region_quad_decimate;
  region_options.threads = 1;  // regions are small: a thread pool costs more than it saves
  auto region = TagDetector::Create(region_options);
  if (!region) return region.error();
  return std::unique_ptr<TagTracker>(new TagTracker(tracker, std::move(*full), std::move(*region)));
}

void TagTracker::Reset() {
  tracks_.clear();
  have_full_ = false;
}

std::map<TagId, QuadCorners> TagTracker::Predict(FrameId frame,
                                                 const std::map<TagId, QuadCorners>& predicted) const {
  std::map<TagId, QuadCorners> out = predicted;
  for (const auto& [id, track] : tracks_) {
    if (out.count(id)) continue;
    QuadCorners corners = track.corners;
    if (track.previous && track.frame != track.previous_frame) {
      const double steps = static_cast<double>(frame - track.frame) / static_cast<double>(track.frame - track.previous_frame);
      for (int k = 0; k < 4; ++k) corners[k] += steps * (track.corners[k] - (*track.previous)[k]);
    }
    out[id] = corners;
  }
  return out;
}

Result<DetectionSet> TagTracker::DetectFullFrame(const cv::Mat& gray8, FrameId frame) {
  ++stats_.full_frame_detections;
  frames_since_full_ = 0;
  have_full_ = true;
  return full_detector_->Detect(gray8, frame);
}

void TagTracker::Update(const DetectionSet& detections) {
  std::map<TagId, TagTrack> next;
  for (const TagDetection& tag : detections.tags) {
    TagTrack track;
    track.corners = tag.corners;
    track.frame = detections.frame;
    const auto old = tracks_.find(tag.id);
    if (old != tracks_.end()) {
      track.previous = old->second.corners;
      track.previous_frame = old->second.frame;
    }
    next[tag.id] = track;
  }
  tracks_ = std::move(next);
}

namespace {

// The padded, clipped bounding box of predicted corners; empty when off-image.
cv::Rect RegionOf(const QuadCorners& corners, const TagTrackerOptions& options, const cv::Size& image) {
  double x0 = 1e18, y0 = 1e18, x1 = -1e18, y1 = -1e18;
  for (const Eigen::Vector2d& c : corners) {
    x0 = std::min(x0, c.x());
    y0 = std::min(y0, c.y());
    x1 = std::max(x1, c.x());
    y1 = std::max(y1, c.y());
  }
  if (!(x1 >= x0 && y1 >= y0) || !std::isfinite(x0 + y0 + x1 + y1)) return {};
  const double pad = std::max(options.padding_px, options.padding_fraction * std::max(x1 - x0, y1 - y0));
  const int left = std::max(0, static_cast<int>(std::floor(x0 - pad)));
  const int top = std::max(0, static_cast<int>(std::floor(y0 - pad)));
  const int right = std::min(image.width, static_cast<int>(std::ceil(x1 + pad)) + 1);
  const int bottom = std::min(image.height, static_cast<int>(std::ceil(y1 + pad)) + 1);
  if (right <= left || bottom <= top) return {};
  return cv::Rect(left, top, right - left, bottom - top);
}

// Overlapping regions merged, so that no tag is searched (and found) twice.
std::vector<cv::Rect> MergeOverlapping(std::vector<cv::Rect> regions) {
  bool merged = true;
  while (merged) {
    merged = false;
    for (size_t i = 0; i < regions.size() && !merged; ++i) {
      for (size_t j = i + 1; j < regions.size() && !merged; ++j) {
        if ((regions[i] & regions[j]).area() > 0) {
          regions[i] |= regions[j];
          regions.erase(regions.begin() + static_cast<long>(j));
          merged = true;
        }
      }
    }
  }
  return regions;
}

}  // namespace

Result<DetectionSet> TagTracker::Track(const cv::Mat& gray8, FrameId frame,
                                       const std::map<TagId, QuadCorners>& predicted) {
  ++stats_.frames;
  const bool scheduled = !have_full_ || frames_since_full_ + 1 >= options_.full_frame_every;
  const std::map<TagId, QuadCorners> expected = Predict(frame, predicted);
  if (scheduled || expected.empty() || gray8.empty()) {
    auto detections = DetectFullFrame(gray8, frame);
    if (detections) Update(*detections);
    return detections;
  }
  ++frames_since_full_;

  std::vector<cv::Rect> regions;
  for (const auto& [id, corners] : expected) {
    const cv::Rect region = RegionOf(corners, options_, gray8.size());
    if (region.area() > 0) regions.push_back(region);
  }
  DetectionSet result;
  result.frame = frame;
  for (const cv::Rect& region : MergeOverlapping(std::move(regions))) {
    ++stats_.region_detections;
    auto found = region_detector_->Detect(gray8(region), frame);  // a view: no copy
    if (!found) return found.error();
    const Eigen::Vector2d offset(region.x, region.y);
    for (TagDetection& tag : found->tags) {
      for (Eigen::Vector2d& c : tag.corners) c += offset;
      result.tags.push_back(tag);
    }
  }
  // A tag expected but not found: the prediction failed or the tag left the
  // view. Only a full-frame detection tells which, so run one now.
  std::set<TagId> found_ids;
  for (const TagDetection& tag : result.tags) found_ids.insert(tag.id);
  bool lost = false;
  for (const auto& [id, corners] : expected) {
    if (!found_ids.count(id) && RegionOf(corners, options_, gray8.size()).area() > 0) lost = true;
  }
  if (lost) {
    ++stats_.recoveries;
    auto detections = DetectFullFrame(gray8, frame);
    if (detections) Update(*detections);
    return detections;
  }
  std::sort(result.tags.begin(), result.tags.end(),
            [](const TagDetection& a, const TagDetection& b) { return a.id < b.id; });
  Update(result);
  return result;
}

}  // namespace tagsfm
