#pragma once
// Frames recorded and waiting for the pipeline, so that capture never waits.
// When the pipeline falls behind by more than `capacity` frames the oldest
// waiting one is dropped from live processing only (it is on disk; a replay
// sees it), and counted.
#include <condition_variable>
#include <deque>
#include <mutex>
#include <optional>

#include "tagsfm/capture/frame.h"

namespace tagsfm {

class FrameQueue {
 public:
  explicit FrameQueue(size_t capacity) : capacity_(capacity) {}
  void Push(const Frame& frame);
  // No more frames will come.
  void Close();
  // The next frame, or nullopt once closed and drained.
  std::optional<Frame> Pop();
  size_t dropped() const;

 private:
  mutable std::mutex mutex_;
  std::condition_variable ready_;
  std::deque<Frame> frames_;
  size_t capacity_;
  size_t dropped_ = 0;
  bool closed_ = false;
};

}  // namespace tagsfm
