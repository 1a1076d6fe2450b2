#pragma once
// The loops that feed a Pipeline: a recording's frames in order (replay,
// optionally paced at their timestamps), or a live source recorded to disk
// on its own thread while the pipeline takes frames from a queue (run), so
// that capture never waits.
#include <atomic>
#include <functional>

#include "tagsfm/capture/frame_source.h"
#include "tagsfm/capture/recorder.h"
#include "tagsfm/capture/recording.h"
#include "tagsfm/capture/recording_writer.h"
#include "tagsfm/pipeline/pipeline.h"

namespace tagsfm {

using OutputCallback = std::function<void(const FrameOutput&)>;

// Frames of a recording by id, read again on demand.
FrameLoader RecordingFrameLoader(const RecordingReader& reader);
// The same for a recording still being written: opened at the first call,
// and again for a frame recorded since.
FrameLoader LazyRecordingFrameLoader(std::filesystem::path dir);

struct ReplayLoopOptions {
  bool realtime = false;  // each frame no earlier than its timestamp says
  OutputCallback on_output;
  std::function<void(size_t done, size_t total)> on_progress;
};

struct ReplayLoopSummary {
  int late_frames = 0;  // realtime: frames processed more than 100 ms after their time
};

ReplayLoopSummary ReplayRecording(const RecordingReader& reader, Pipeline& pipeline, const ReplayLoopOptions& options);

struct LiveLoopOptions {
  size_t max_frames = 0;         // 0: until the source ends or a stop is asked for
  size_t max_queue_frames = 60;  // frames waiting for the pipeline before live drops some
  OutputCallback on_output;
};

struct LiveLoopSummary {
  RecordSummary recorded;
  size_t dropped = 0;  // recorded, but not processed live
};

LiveLoopSummary RunLive(FrameSource& source, RecordingWriter& writer, Pipeline& pipeline, const std::atomic<bool>& stop,
                        const LiveLoopOptions& options);

}  // namespace tagsfm
