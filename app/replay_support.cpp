#include "replay_support.h"

#include <unistd.h>

#include <cstdio>

namespace tagsfm {

Result<std::unique_ptr<TagDetector>> DetectorForRecording(const RecordingInfo& info) {
  TagDetectorOptions options;
  options.family = info.targets.family;
  return TagDetector::Create(options);
}

const char* TagSearchName(TagSearch search) {
  return search == TagSearch::kTracking ? "tracking" : "every_frame";
}

Result<TagSearch> ParseTagSearch(const std::string& name) {
  if (name == "tracking") return TagSearch::kTracking;
  if (name == "every_frame") return TagSearch::kEveryFrame;
  return MakeError("tag search must be tracking or every_frame (got '" + name + "')");
}

Result<std::unique_ptr<TagTracker>> TagSearchForRecording(const RecordingInfo& info, TagSearch search) {
  TagDetectorOptions detector;
  detector.family = info.targets.family;
  TagTrackerOptions tracker;
  if (search == TagSearch::kEveryFrame) {
    tracker.full_frame_every = 1;  // every frame is a scheduled full-frame pass
    // Photo sets: the lens in the edge fit (straight edges in undistorted
    // pixels), ~0.1 ms more per tag, which tracking cannot spare at video rates.
    detector.camera = info.camera;
  }
  return TagTracker::Create(detector, tracker);
}

bool StderrIsTerminal() { return ::isatty(STDERR_FILENO) == 1; }

ProgressLine::ProgressLine(std::string stage, size_t total)
    : stage_(std::move(stage)), total_(total), enabled_(StderrIsTerminal()),
      start_(std::chrono::steady_clock::now()), last_(start_) {}

void ProgressLine::Update(size_t done) {
  if (!enabled_) return;
  const auto now = std::chrono::steady_clock::now();
  if (now - last_ < std::chrono::milliseconds(250) && done < total_) return;
  last_ = now;
  const double elapsed = std::chrono::duration<double>(now - start_).count();
  const double fps = elapsed > 0 ? static_cast<double>(done) / elapsed : 0.0;
  const double left = fps > 0 ? static_cast<double>(total_ - done) / fps : 0.0;
  std::fprintf(stderr, "\r[%s] %zu/%zu frames  %.1f fps  %.0f s left   ", stage_.c_str(), done, total_, fps, left);
  std::fflush(stderr);
}

void ProgressLine::Done() {
  if (!enabled_) return;
  std::fprintf(stderr, "\n");
}

}  // namespace tagsfm
