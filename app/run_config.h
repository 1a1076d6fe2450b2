#pragma once
// The live daemon's config file (`tagsfm run --config FILE`): the camera
// settings (`capture:`, see firmware_config/), the camera model and targets
// (`camera:`, `targets:`, as in recording.yaml; optional when the source is a
// recording, which knows them), the daemon's own `run:` block, and the
// pipeline's options (`pipeline:`, as for `replay --config`).
// firmware_config/README.md documents every field.
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "tagsfm/capture/capture_settings.h"
#include "tagsfm/capture/recording.h"
#include "tagsfm/pipeline/pipeline_options.h"

namespace YAML {
class Node;
}

namespace tagsfm {

struct RunConfig {
  CaptureSettings capture;
  std::optional<RecordingInfo> info;       // camera and targets, when the file gives them
  std::string record_dir;                  // the recording the daemon writes
  std::string results_dir;                 // result files when capture ends (default RECORD/results)
  std::string dashboard = "127.0.0.1:8080";
  size_t max_queue_frames = 60;            // frames waiting for reconstruction before live drops some
  // run.tag_search and run.point_error_goal_mm are short forms of
  // pipeline.tag_search and pipeline.feedback.point_error_goal_m.
  PipelineOptions pipeline;

  Status Check() const;
};

Result<RunConfig> ReadRunConfig(const std::filesystem::path& path);

// The run: block into *config, every field; each error names the file and
// the field (an unknown field is one).
std::vector<std::string> ReadRunBlock(const YAML::Node& run, const std::string& file, RunConfig* config);

// Every error of a config file, one line each naming the file and the field
// (empty: the file is valid). A wrong field does not hide the next: the
// capture: and pipeline: blocks are read one field at a time, the run:
// block field by field, camera: and targets: together (their fields depend
// on each other), and then the whole file for what shows only together.
std::vector<std::string> CheckRunConfigFile(const std::filesystem::path& path);

}  // namespace tagsfm
