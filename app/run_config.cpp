#include "run_config.h"
#include "tagsfm/capture/yaml_file.h"

#include <algorithm>
#include <functional>

#include <yaml-cpp/yaml.h>

namespace tagsfm {
namespace {

// "HOST:PORT", port 0-65535 (0: any free one).
Status CheckAddress(const std::string& address) {
  const size_t colon = address.rfind(':');
  const std::string port = colon == std::string::npos ? "" : address.substr(colon + 1);
  const bool digits = !port.empty() && port.size() <= 5 && std::all_of(port.begin(), port.end(), ::isdigit);
  if (colon == 0 || !digits || std::stoi(port) > 65535) {
    return MakeError("run.dashboard must be HOST:PORT with a port of 0-65535 (got '" + address + "')");
  }
  return Status::Ok();
}

using FieldReader = std::function<Status(const YAML::Node&, RunConfig*)>;

// One reader per run: field; each says what is wrong with its own field.
const std::vector<std::pair<std::string, FieldReader>>& RunFields() {
  static const std::vector<std::pair<std::string, FieldReader>> fields = {
      {"record_dir", [](const YAML::Node& v, RunConfig* c) { c->record_dir = v.as<std::string>(); return Status::Ok(); }},
      {"results_dir", [](const YAML::Node& v, RunConfig* c) { c->results_dir = v.as<std::string>(); return Status::Ok(); }},
      {"dashboard",
       [](const YAML::Node& v, RunConfig* c) {
         c->dashboard = v.as<std::string>();
         return CheckAddress(c->dashboard);
       }},
      {"max_queue_frames",
       [](const YAML::Node& v, RunConfig* c) {
         const long frames = v.as<long>();
         if (frames < 1) return Status(MakeError("run.max_queue_frames must be >= 1"));
         c->max_queue_frames = static_cast<size_t>(frames);
         return Status::Ok();
       }},
      {"point_error_goal_mm",
       [](const YAML::Node& v, RunConfig* c) {
         const double mm = v.as<double>();
         if (!(mm > 0)) return Status(MakeError("run.point_error_goal_mm must be > 0"));
         c->pipeline.feedback.point_error_goal_m = mm / 1000.0;
         return Status::Ok();
       }},
      {"tag_search",
       [](const YAML::Node& v, RunConfig* c) {
         auto search = ParseTagSearch(v.as<std::string>());
         if (!search) return Status(MakeError("run.tag_search: " + search.error().message));
         c->pipeline.tag_search = *search;
         return Status::Ok();
       }},
  };
  return fields;
}

}  // namespace

std::vector<std::string> ReadRunBlock(const YAML::Node& run, const std::string& file, RunConfig* config) {
  std::vector<std::string> errors;
  if (!run) return errors;
  if (!run.IsMap()) return {file + ": run must be a mapping"};
  for (const auto& [key, read] : RunFields()) {
    if (!run[key]) continue;
    try {
      if (Status s = read(run[key], config); !s) errors.push_back(file + ": " + s.error().message);
    } catch (const YAML::Exception&) {
      errors.push_back(file + ": run." + key + " has the wrong type: '" + YAML::Dump(run[key]) + "'");
    }
  }
  for (const auto& entry : run) {
    const std::string key = YamlKeyText(entry.first);
    const auto& fields = RunFields();
    if (std::none_of(fields.begin(), fields.end(), [&](const auto& f) { return f.first == key; })) {
      errors.push_back(file + ": run." + key + " is not a field of run: (see firmware_config/README.md)");
    }
  }
  return errors;
}

namespace {

Result<YAML::Node> LoadRoot(const std::string& file) {
  try {
    return YAML::LoadFile(file);
  } catch (const YAML::BadFile&) {
    return MakeError(file + ": cannot be read");
  } catch (const YAML::Exception& e) {
    return MakeError(file + ": not valid YAML (line " + std::to_string(e.mark.line + 1) + ")");
  }
}

}  // namespace

Status RunConfig::Check() const {
  if (Status s = capture.Check(); !s) return s;
  if (record_dir.empty()) return MakeError("run.record_dir is missing: where should the recording go?");
  if (max_queue_frames < 1) return MakeError("run.max_queue_frames must be >= 1");
  if (Status s = CheckAddress(dashboard); !s) return s;
  if (Status s = pipeline.Check(); !s) return s;
  return Status::Ok();
}

Result<RunConfig> ReadRunConfig(const std::filesystem::path& path) {
  const std::string file = path.string();
  RunConfig config;
  auto capture = ReadCaptureSettings(path);
  if (!capture) return capture.error();
  config.capture = *capture;
  auto root = LoadRoot(file);
  if (!root) return root.error();
  if ((*root)["targets"]) {
    auto info = ReadCameraAndTargets(path);
    if (!info) return info.error();
    config.info = *info;
    // A map named in the config is relative to the config, not to where the daemon starts.
    const std::filesystem::path map(config.info->targets.map);
    if (!map.empty() && map.is_relative()) config.info->targets.map = (path.parent_path() / map).string();
  }
  if (auto errors = ReadRunBlock((*root)["run"], file, &config); !errors.empty()) return MakeError(errors.front());
  if (Status s = ReadPipelineOptions((*root)["pipeline"], path, &config.pipeline); !s) return s.error();
  if (config.results_dir.empty() && !config.record_dir.empty()) {
    config.results_dir = (std::filesystem::path(config.record_dir) / "results").string();
  }
  if (Status s = config.Check(); !s) return MakeError(file + ": " + s.error().message);
  return config;
}

}  // namespace tagsfm
