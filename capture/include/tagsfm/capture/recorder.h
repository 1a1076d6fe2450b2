#pragma once
// The capture loop of `tagsfm record` (and of the live daemon's recording):
// frames from a source into a recording until the source ends, a stop is
// asked for, or the source fails. Whatever was written stays written.
#include <atomic>
#include <functional>
#include <optional>

#include "tagsfm/capture/frame_source.h"
#include "tagsfm/capture/recording_writer.h"

namespace tagsfm {

struct RecordSummary {
  size_t frames_written = 0;
  bool source_ended = false;          // a recording played to its end
  std::optional<Error> error;         // the source or the disk failed
};

// `on_frame` (optional) sees each frame after it is safely on disk, e.g. to
// pass it on to reconstruction; its `source` is then the recorded file. `max_frames` 0 means no limit.
RecordSummary RecordFrames(FrameSource& source, RecordingWriter& writer, const std::atomic<bool>& stop,
                           size_t max_frames = 0, const std::function<void(const Frame&)>& on_frame = {});

}  // namespace tagsfm
