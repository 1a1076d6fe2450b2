#include "tagsfm/capture/recorder.h"

namespace tagsfm {

RecordSummary RecordFrames(FrameSource& source, RecordingWriter& writer, const std::atomic<bool>& stop,
                           size_t max_frames, const std::function<void(const Frame&)>& on_frame) {
  RecordSummary summary;
  while (!stop.load() && (max_frames == 0 || summary.frames_written < max_frames)) {
    auto next = source.Next();
    if (!next) {
      summary.error = next.error();
      break;
    }
    if (!next->has_value()) {
      summary.source_ended = true;
      break;
    }
    Frame& frame = **next;
    auto file = writer.Append(frame);
    if (!file) {
      summary.error = file.error();
      break;
    }
    ++summary.frames_written;
    frame.source = file->string();
    if (on_frame) on_frame(frame);
  }
  return summary;
}

}  // namespace tagsfm
