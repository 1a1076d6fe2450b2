#pragma once
// What `replay`, `run` and `calibrate` print: errors, the pipeline's
// warnings, a progress line for terminals, the summary of a replay.
#include <chrono>
#include <string>

#include "tagsfm/core/result.h"
#include "tagsfm/pipeline/pipeline.h"

namespace tagsfm {

// Logs the error and returns `exit_code`.
int Fail(const Error& error, int exit_code);
void LogWarnings(Pipeline& pipeline);
void LogCalibratedCamera(const ReconstructionResult& result);
void PrintReplaySummary(const ReconstructionResult& result, const RunStats& stats, const std::string& out);

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
