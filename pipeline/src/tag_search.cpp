#include "tagsfm/pipeline/tag_search.h"

namespace tagsfm {

const char* TagSearchName(TagSearch search) { return search == TagSearch::kTracking ? "tracking" : "every_frame"; }

Result<TagSearch> ParseTagSearch(const std::string& name) {
  if (name == "tracking") return TagSearch::kTracking;
  if (name == "every_frame") return TagSearch::kEveryFrame;
  return MakeError("tag search must be tracking or every_frame (got '" + name + "')");
}

Result<std::unique_ptr<TagTracker>> MakeTagSearch(const RecordingInfo& info, TagSearch search,
                                                  TagDetectorOptions detector, TagTrackerOptions tracker) {
  detector.family = info.targets.family;
  if (search == TagSearch::kEveryFrame) {
    tracker.full_frame_every = 1;  // every frame is a scheduled full-frame pass
    // Photo sets: the lens in the edge fit (straight edges in undistorted
    // pixels), ~0.1 ms more per tag, which tracking cannot spare at video rates.
    detector.camera = info.camera;
  }
  return TagTracker::Create(detector, tracker);
}

}  // namespace tagsfm
