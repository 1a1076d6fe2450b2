#pragma once
// One frame's way from capture to a result, the same for `replay`,
// `replay --realtime`, `run` and `calibrate` (docs/architecture.md): find
// the tags (tracking, fed the reconstruction's predictions, or a full-frame
// detection), register the frame and adjust (recon/), select and track
// feature keyframes, give live feedback; at the end the final adjustment,
// the feature points and the run's statistics. A recording without
// intrinsics is calibrated from its targets first: its frames' tags are kept
// until Finish, which calibrates and then reconstructs them.
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "tagsfm/capture/frame.h"
#include "tagsfm/capture/recording.h"
#include "tagsfm/export/run_stats.h"
#include "tagsfm/pipeline/pipeline_options.h"
#include "tagsfm/recon/reconstruction.h"

namespace tagsfm {

// A frame again, by id: for features tracked at Finish and for frames kept
// while calibrating. Its `source` names the image file.
using FrameLoader = std::function<Result<Frame>(FrameId)>;

struct PipelineInput {
  RecordingInfo info;                       // no camera: calibrated from the targets at Finish
  std::optional<TargetCornerMap> known_map;  // targets held fixed
  FrameLoader reload;                       // needed for feature work dropped live and calibration
  std::string where = "recording.yaml";     // the file the info came from, for messages
};

struct FrameOutput {
  FrameId frame = 0;
  std::int64_t timestamp_ns = 0;
  std::optional<std::string> skipped;  // why the frame was left out (unreadable, detection failed)
  DetectionSet detections;
  std::optional<FrameReport> report;   // none when skipped, or while the intrinsics are still unknown
  std::optional<LiveStatus> status;    // with options.live_feedback, once reconstructing
};

struct PipelineResult {
  ReconstructionResult reconstruction;
  RunStats stats;
};

class Pipeline {
 public:
  static Result<std::unique_ptr<Pipeline>> Create(const PipelineInput& input, const PipelineOptions& options);
  ~Pipeline();
  Pipeline(const Pipeline&) = delete;
  Pipeline& operator=(const Pipeline&) = delete;

  FrameOutput Process(const Frame& frame);
  // A frame that could not be read: counted and named in the report.
  FrameOutput Skip(FrameId frame, const std::string& why);
  // Calibrates if needed, adjusts everything, triangulates the features.
  // Call once.
  Result<PipelineResult> Finish();

  // Warnings since the last call (features that failed, frames not reloaded), one line each.
  std::vector<std::string> TakeWarnings();
  // The camera once known (given, or calibrated at Finish).
  const std::optional<CameraModel>& camera() const;

 private:
  struct State;
  explicit Pipeline(std::unique_ptr<State> state);
  std::unique_ptr<State> state_;
};

}  // namespace tagsfm
