#pragma once
// Pieces shared by `replay`, `run` and `calibrate`: the detector a recording
// asks for, how the pipeline searches a stream of frames for tags, and a
// progress line for terminals.
#include <chrono>
#include <memory>
#include <string>

#include "tagsfm/capture/recording.h"
#include "tagsfm/detect/tag_detector.h"
#include "tagsfm/detect/tag_tracker.h"

namespace tagsfm {

// The detector for a recording's tag family, sub-pixel corners on.
Result<std::unique_ptr<TagDetector>> DetectorForRecording(const RecordingInfo& info);

// How `replay` and `run` find the tags of frame after frame. Tracking (the
// default): libapriltag only around where the tags of the frames before
// are, plus entry bands, with a full-frame pass every 15 frames and at once
// when a tag is lost (docs/detection.md: 3-4x less time per frame than
// full-frame detection on video, same recall). Every frame: a full-frame
// detection on each frame, for photo sets, where nothing carries over from
// one frame to the next (tracking gives the same tags there, but tries the
// stale regions first), with the recording's lens model in the corners'
// edge fit (docs/detection.md, "Lens distortion").
enum class TagSearch { kTracking, kEveryFrame };
const char* TagSearchName(TagSearch search);                  // "tracking", "every_frame"
Result<TagSearch> ParseTagSearch(const std::string& name);

// Tags of a recording's frames, in order, searched as `search` says.
Result<std::unique_ptr<TagTracker>> TagSearchForRecording(const RecordingInfo& info, TagSearch search);

bool StderrIsTerminal();

// "\r[stage] 120/500 frames  35.2 fps  11 s left" on stderr, at most 4 times a second.
class ProgressLine {
 public:
  ProgressLine(std::string stage, size_t total);
  void Update(size_t done);
  void Done();

 private:
  std::string stage_;
  size_t total_;
  bool enabled_;
  std::chrono::steady_clock::time_point start_, last_;
};

}  // namespace tagsfm
