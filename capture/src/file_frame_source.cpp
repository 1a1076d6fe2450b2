// file:REC[?rate=max] — a recording played back as if it were a camera.
#include <chrono>
#include <thread>

#include "tagsfm/capture/frame_source.h"

namespace tagsfm {
namespace {

class FileFrameSource : public FrameSource {
 public:
  FileFrameSource(RecordingReader reader, bool as_fast_as_possible, std::string uri)
      : reader_(std::move(reader)), fast_(as_fast_as_possible), uri_(std::move(uri)) {}

  Result<std::optional<Frame>> Next() override {
    if (next_ >= reader_.entries().size()) return std::optional<Frame>();
    const FrameEntry& entry = reader_.entries()[next_];
    if (!fast_) WaitForTimestamp(entry.timestamp_ns);
    auto frame = reader_.LoadFrame(next_++);
    if (!frame) return frame.error();
    return std::optional<Frame>(std::move(*frame));
  }
  const RecordingInfo& info() const override { return reader_.info(); }
  std::string uri() const override { return uri_; }

 private:
  // Paces playback at the recording's own timestamps, relative to its first.
  void WaitForTimestamp(std::int64_t timestamp_ns) {
    const auto now = std::chrono::steady_clock::now();
    if (!started_) {
      started_ = true;
      start_wall_ = now;
      start_stamp_ns_ = timestamp_ns;
      return;
    }
    const auto due = start_wall_ + std::chrono::nanoseconds(timestamp_ns - start_stamp_ns_);
    if (due > now) std::this_thread::sleep_until(due);
  }

  RecordingReader reader_;
  bool fast_;
  std::string uri_;
  size_t next_ = 0;
  bool started_ = false;
  std::chrono::steady_clock::time_point start_wall_;
  std::int64_t start_stamp_ns_ = 0;
};

}  // namespace

Result<std::unique_ptr<FrameSource>> OpenFileFrameSource(const std::string& uri, const std::string& spec) {
  std::string path = spec;
  bool fast = false;
  if (const size_t q = spec.find('?'); q != std::string::npos) {
    path = spec.substr(0, q);
    const std::string query = spec.substr(q + 1);
    if (query == "rate=max") {
      fast = true;
    } else if (query != "rate=realtime") {
      return MakeError(uri + ": unknown option '" + query + "' (known: rate=max, rate=realtime)");
    }
  }
  auto reader = RecordingReader::Open(path);
  if (!reader) return reader.error();
  return std::unique_ptr<FrameSource>(new FileFrameSource(std::move(*reader), fast, uri));
}

}  // namespace tagsfm
