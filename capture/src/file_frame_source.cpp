// file:REC[?rate=max] — a recording played back as if it were a camera.

#include "tagsfm/capture/frame_source.h"
#include "tagsfm/capture/timestamp_pacer.h"

namespace tagsfm {
namespace {

class FileFrameSource : public FrameSource {
 public:
  FileFrameSource(RecordingReader reader, bool as_fast_as_possible, std::string uri)
      : reader_(std::move(reader)), info_(reader_.info()), fast_(as_fast_as_possible), uri_(std::move(uri)) {
    // The map a recording names is relative to the recording, not to
    // whoever plays it as a camera.
    const std::filesystem::path map(info_.targets.map);
    if (!map.empty() && map.is_relative()) info_.targets.map = (reader_.dir() / map).string();
  }

  Result<std::optional<Frame>> Next() override {
    if (next_ >= reader_.entries().size()) return std::optional<Frame>();
    const FrameEntry& entry = reader_.entries()[next_];
    if (!fast_) pacer_.WaitFor(entry.timestamp_ns);
    auto frame = reader_.LoadFrame(next_++);
    if (!frame) return frame.error();
    return std::optional<Frame>(std::move(*frame));
  }
  const RecordingInfo& info() const override { return info_; }
  std::string uri() const override { return uri_; }

 private:
  RecordingReader reader_;
  RecordingInfo info_;
  bool fast_;
  std::string uri_;
  size_t next_ = 0;
  TimestampPacer pacer_;  // plays at the recording's own timestamps
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
