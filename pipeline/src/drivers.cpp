#include "tagsfm/pipeline/drivers.h"

#include <map>
#include <memory>
#include <thread>

#include "tagsfm/capture/timestamp_pacer.h"
#include "tagsfm/pipeline/frame_queue.h"

namespace tagsfm {
namespace {

// frames.csv rows by frame id.
std::map<FrameId, size_t> EntryIndex(const RecordingReader& reader) {
  std::map<FrameId, size_t> index;
  for (size_t i = 0; i < reader.entries().size(); ++i) index[reader.entries()[i].frame] = i;
  return index;
}

Result<Frame> LoadById(const RecordingReader& reader, const std::map<FrameId, size_t>& index, FrameId frame) {
  const auto it = index.find(frame);
  if (it == index.end()) {
    return MakeError(reader.dir().string() + ": frame " + std::to_string(frame) + " is not in frames.csv");
  }
  return reader.LoadFrame(it->second);
}

}  // namespace

FrameLoader RecordingFrameLoader(const RecordingReader& reader) {
  auto index = std::make_shared<const std::map<FrameId, size_t>>(EntryIndex(reader));
  return [&reader, index](FrameId frame) { return LoadById(reader, *index, frame); };
}

FrameLoader LazyRecordingFrameLoader(std::filesystem::path dir) {
  struct Opened {
    Result<RecordingReader> reader;
    std::map<FrameId, size_t> index;
  };
  auto opened = std::make_shared<std::optional<Opened>>();
  return [opened, dir](FrameId frame) -> Result<Frame> {
    // Opened again for a frame recorded after the last opening (a keyframe
    // the bootstrap held back is read while the recording grows).
    if (opened->has_value() && (*opened)->reader && !(*opened)->index.count(frame)) opened->reset();
    if (!opened->has_value()) {
      auto reader = RecordingReader::Open(dir);
      std::map<FrameId, size_t> index = reader ? EntryIndex(*reader) : std::map<FrameId, size_t>{};
      opened->emplace(Opened{std::move(reader), std::move(index)});
    }
    const Opened& o = **opened;
    if (!o.reader) return o.reader.error();
    return LoadById(*o.reader, o.index, frame);
  };
}

ReplayLoopSummary ReplayRecording(const RecordingReader& reader, Pipeline& pipeline, const ReplayLoopOptions& options) {
  TimestampPacer pacer;
  const auto& entries = reader.entries();
  for (size_t i = 0; i < entries.size(); ++i) {
    if (options.realtime) pacer.WaitFor(entries[i].timestamp_ns);
    auto frame = reader.LoadFrame(i);
    const FrameOutput out = frame ? pipeline.Process(*frame) : pipeline.Skip(entries[i].frame, frame.error().message);
    if (options.on_output) options.on_output(out);
    if (options.on_progress) options.on_progress(i + 1, entries.size());
  }
  return ReplayLoopSummary{pacer.late_frames()};
}

LiveLoopSummary RunLive(FrameSource& source, RecordingWriter& writer, Pipeline& pipeline, const std::atomic<bool>& stop,
                        const LiveLoopOptions& options) {
  FrameQueue queue(options.max_queue_frames);
  LiveLoopSummary summary;
  std::thread capture([&] {
    summary.recorded = RecordFrames(source, writer, stop, options.max_frames, [&](const Frame& f) { queue.Push(f); });
    queue.Close();
  });
  while (auto frame = queue.Pop()) {
    const FrameOutput out = pipeline.Process(*frame);
    if (options.on_output) options.on_output(out);
  }
  capture.join();
  summary.dropped = queue.dropped();
  return summary;
}

}  // namespace tagsfm
