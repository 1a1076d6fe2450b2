#include "run_config.h"

#include <yaml-cpp/yaml.h>

namespace tagsfm {

Status RunConfig::Check() const {
  if (Status s = capture.Check(); !s) return s;
  if (record_dir.empty()) return MakeError("run.record_dir is missing: where should the recording go?");
  if (max_queue_frames < 1) return MakeError("run.max_queue_frames must be >= 1");
  if (Status s = pipeline.Check(); !s) return s;
  return Status::Ok();
}

Result<RunConfig> ReadRunConfig(const std::filesystem::path& path) {
  const std::string file = path.string();
  RunConfig config;
  auto capture = ReadCaptureSettings(path);
  if (!capture) return capture.error();
  config.capture = *capture;
  YAML::Node root;
  try {
    root = YAML::LoadFile(file);
  } catch (const YAML::Exception& e) {
    return MakeError(file + ": not valid YAML");
  }
  if (root["targets"]) {
    auto info = ReadCameraAndTargets(path);
    if (!info) return info.error();
    config.info = *info;
    // A map named in the config is relative to the config, not to where the daemon starts.
    const std::filesystem::path map(config.info->targets.map);
    if (!map.empty() && map.is_relative()) config.info->targets.map = (path.parent_path() / map).string();
  }
  const YAML::Node run = root["run"];
  try {
    if (run && run["record_dir"]) config.record_dir = run["record_dir"].as<std::string>();
    if (run && run["results_dir"]) config.results_dir = run["results_dir"].as<std::string>();
    if (run && run["dashboard"]) config.dashboard = run["dashboard"].as<std::string>();
    if (run && run["max_queue_frames"]) config.max_queue_frames = run["max_queue_frames"].as<size_t>();
    if (run && run["point_error_goal_mm"]) config.pipeline.feedback.point_error_goal_m = run["point_error_goal_mm"].as<double>() / 1000.0;
    if (run && run["tag_search"]) {
      auto search = ParseTagSearch(run["tag_search"].as<std::string>());
      if (!search) return MakeError(file + ": run.tag_search: " + search.error().message);
      config.pipeline.tag_search = *search;
    }
  } catch (const YAML::Exception&) {
    return MakeError(file + ": run: a field has the wrong type (record_dir, results_dir, dashboard, tag_search: text; "
                            "max_queue_frames: a whole number; point_error_goal_mm: a number)");
  }
  if (Status s = ReadPipelineOptions(root["pipeline"], path, &config.pipeline); !s) return s.error();
  if (config.results_dir.empty() && !config.record_dir.empty()) {
    config.results_dir = (std::filesystem::path(config.record_dir) / "results").string();
  }
  if (Status s = config.Check(); !s) return MakeError(file + ": " + s.error().message);
  return config;
}

}  // namespace tagsfm
