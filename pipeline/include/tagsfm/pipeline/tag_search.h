#pragma once
// How the pipeline finds the tags of frame after frame. Tracking (the
// default): libapriltag only around where the tags of the frames before
// are, plus entry bands, with a full-frame pass every 15 frames and at once
// when a tag is lost (docs/detection.md: 3-4x less time per frame than
// full-frame detection on video, same recall). Every frame: a full-frame
// detection on each frame, for photo sets, where nothing carries over from
// one frame to the next, with the recording's lens model in the corners'
// edge fit (docs/detection.md, "Lens distortion").
#include <memory>
#include <string>

#include "tagsfm/capture/recording.h"
#include "tagsfm/detect/tag_detector.h"
#include "tagsfm/detect/tag_tracker.h"

namespace tagsfm {

enum class TagSearch { kTracking, kEveryFrame };
const char* TagSearchName(TagSearch search);  // "tracking", "every_frame"
Result<TagSearch> ParseTagSearch(const std::string& name);

// The tracker for a recording's frames: the recording's tag family, and for
// every_frame a full-frame pass on each frame with the lens in the edge fit.
Result<std::unique_ptr<TagTracker>> MakeTagSearch(const RecordingInfo& info, TagSearch search,
                                                  TagDetectorOptions detector, TagTrackerOptions tracker);

}  // namespace tagsfm
