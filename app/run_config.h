#pragma once
// The live daemon's config file (`tagsfm run --config FILE`): the camera
// settings (`capture:`, see firmware_config/), the camera model and targets
// (`camera:`, `targets:`, as in recording.yaml; optional when the source is a
// recording, which knows them), and the daemon's own `run:` block.
#include <filesystem>
#include <optional>
#include <string>

#include "tagsfm/capture/capture_settings.h"
#include "tagsfm/capture/recording.h"
#include "replay_support.h"
#include "tagsfm/feedback/live_feedback.h"

namespace tagsfm {

struct RunConfig {
  CaptureSettings capture;
  std::optional<RecordingInfo> info;       // camera and targets, when the file gives them
  std::string record_dir;                  // the recording the daemon writes
  std::string results_dir;                 // result files when capture ends (default RECORD/results)
  std::string dashboard = "127.0.0.1:8080";
  size_t max_queue_frames = 60;            // frames waiting for reconstruction before live drops some
  TagSearch tag_search = TagSearch::kTracking;  // run.tag_search: tracking or every_frame
  LiveFeedbackOptions feedback;

  Status Check() const;
};

Result<RunConfig> ReadRunConfig(const std::filesystem::path& path);

}  // namespace tagsfm
