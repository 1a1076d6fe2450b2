#include "replay_support.h"

#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <vector>

#include <spdlog/spdlog.h>

namespace tagsfm {

namespace {

// The q-quantile of `values` (0 when empty).
double Percentile(std::vector<double> values, double q) {
  if (values.empty()) return 0.0;
  const size_t i = std::min(values.size() - 1, static_cast<size_t>(q * static_cast<double>(values.size())));
  std::nth_element(values.begin(), values.begin() + static_cast<long>(i), values.end());
  return values[i];
}

}  // namespace

int Fail(const Error& error, int exit_code) {
  spdlog::error("{}", error.message);
  return exit_code;
}

void LogWarnings(Pipeline& pipeline) {
  for (const auto& warning : pipeline.TakeWarnings()) spdlog::warn("{}", warning);
}

void LogCalibratedCamera(const ReconstructionResult& result) {
  const CameraModel& c = result.camera;
  spdlog::info("no camera block: calibrated from the targets and adjusted, fx {:.1f} fy {:.1f} cx {:.1f} cy {:.1f}",
               c.fx, c.fy, c.cx, c.cy);
}

void PrintReplaySummary(const ReconstructionResult& result, const RunStats& stats, const std::string& out) {
  int registered = 0;
  for (const auto& f : result.frames) registered += f.registered;
  std::fprintf(stderr,
               "\n  frames       %d read, %d skipped (unreadable)\n"
               "  registered   %d of %d frames\n"
               "  targets      %zu in the map (%s)\n"
               "  features     %zu points triangulated from the final poses\n"
               "  reprojection %.3f px RMS over %d target corner observations\n"
               "  per frame    %.2f ms p50, %.2f ms p95 (detection aside)\n"
               "  detection    %.2f ms p50 per frame, %s (%d of the frames in full, %d after a lost tag)\n"
               "  runtime      %.1f s, peak memory %.0f MB\n"
               "  results in   %s  (poses.csv, targets.csv, report.json, cloud.ply, colmap/, preview.png)\n\n",
               stats.frames, stats.frames_skipped, registered, stats.frames - stats.frames_skipped,
               result.tags.size(), stats.mode.c_str(), result.feature_points.size(), result.reprojection_rms_px,
               result.observations, Percentile(stats.frame_latency_ms, 0.5), Percentile(stats.frame_latency_ms, 0.95),
               Percentile(stats.detection_ms, 0.5), stats.tag_search.c_str(), stats.full_frame_detections,
               stats.tag_search_recoveries, stats.runtime_s, stats.peak_rss_mb, out.c_str());
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
