#pragma once
// Holds frames back until their timestamp, relative to the first frame's,
// has come on the wall clock: playing a recording at its own pace (the file
// camera source, `replay --realtime`). A frame whose time has passed goes at
// once; frames are never dropped, late ones are counted.
#include <chrono>
#include <cstdint>
#include <optional>
#include <thread>

namespace tagsfm {

class TimestampPacer {
 public:
  // Waits for the frame with this timestamp. `late_after`: a frame more
  // than this behind its time counts as late.
  void WaitFor(std::int64_t timestamp_ns, std::chrono::milliseconds late_after = std::chrono::milliseconds(100)) {
    const auto now = std::chrono::steady_clock::now();
    if (!first_timestamp_ns_) {
      first_timestamp_ns_ = timestamp_ns;
      start_ = now;
      return;
    }
    const auto due = start_ + std::chrono::nanoseconds(timestamp_ns - *first_timestamp_ns_);
    if (due > now) {
      std::this_thread::sleep_until(due);
    } else if (now - due > late_after) {
      ++late_frames_;
    }
  }
  int late_frames() const { return late_frames_; }

 private:
  std::optional<std::int64_t> first_timestamp_ns_;
  std::chrono::steady_clock::time_point start_;
  int late_frames_ = 0;
};

}  // namespace tagsfm
