#pragma once
// Pieces shared by `replay` and `calibrate`: the detector a recording asks
// for, and a progress line for terminals.
#include <chrono>
#include <memory>
#include <string>

#include "tagsfm/capture/recording.h"
#include "tagsfm/detect/tag_detector.h"

namespace tagsfm {

// The detector for a recording's tag family, sub-pixel corners on.
Result<std::unique_ptr<TagDetector>> DetectorForRecording(const RecordingInfo& info);

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
