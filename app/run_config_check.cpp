// tagsfm run --check-config FILE: every error of a config, not only the
// first, so that a technician fixes a rig's file in one go.
#include <unistd.h>

#include <algorithm>
#include <fstream>

#include <yaml-cpp/yaml.h>

#include "run_config.h"
#include "tagsfm/capture/yaml_file.h"

namespace tagsfm {
namespace {

using LeafPath = std::vector<std::string>;

// The paths of a mapping's leaves (a list is one leaf).
void CollectLeaves(const YAML::Node& node, LeafPath& path, std::vector<LeafPath>* leaves) {
  if (!node.IsMap()) {
    leaves->push_back(path);
    return;
  }
  for (const auto& entry : node) {
    path.push_back(YamlKeyText(entry.first));
    CollectLeaves(entry.second, path, leaves);
    path.pop_back();
  }
}

// `block` with only the leaf at `path`, nested as it was.
YAML::Node OnlyLeaf(const YAML::Node& block, const LeafPath& path, size_t depth = 0) {
  if (depth == path.size()) return YAML::Clone(block);
  YAML::Node only(YAML::NodeType::Map);
  only[path[depth]] = OnlyLeaf(block[path[depth]], path, depth + 1);
  return only;
}

std::vector<LeafPath> Leaves(const YAML::Node& block) {
  std::vector<LeafPath> leaves;
  LeafPath path;
  if (block && block.IsMap()) CollectLeaves(block, path, &leaves);
  return leaves;
}

void AddOnce(std::vector<std::string>* errors, const std::string& error) {
  if (std::find(errors->begin(), errors->end(), error) == errors->end()) errors->push_back(error);
}

// ReadCaptureSettings reads a file: each capture field goes alone into a
// scratch file, and its errors are told with the real file's name.
void CheckCaptureFields(const YAML::Node& capture, const std::string& file, std::vector<std::string>* errors) {
  if (capture && !capture.IsMap()) return AddOnce(errors, file + ": capture must be a mapping");
  const auto scratch = std::filesystem::temp_directory_path() / ("tagsfm-check-" + std::to_string(::getpid()) + ".yaml");
  for (const LeafPath& leaf : Leaves(capture)) {
    YAML::Node alone(YAML::NodeType::Map);
    alone["capture"] = OnlyLeaf(capture, leaf);
    std::ofstream(scratch) << YAML::Dump(alone) << "\n";
    auto read = ReadCaptureSettings(scratch);
    if (read) continue;
    std::string message = read.error().message;
    for (size_t at; (at = message.find(scratch.string())) != std::string::npos;) message.replace(at, scratch.string().size(), file);
    AddOnce(errors, message);
  }
  std::error_code ignored;
  std::filesystem::remove(scratch, ignored);
}

void CheckPipelineFields(const YAML::Node& pipeline, const std::filesystem::path& path, std::vector<std::string>* errors) {
  if (pipeline && !pipeline.IsMap()) return AddOnce(errors, path.string() + ": pipeline must be a mapping");
  for (const LeafPath& leaf : Leaves(pipeline)) {
    PipelineOptions options;
    if (Status s = ReadPipelineOptions(OnlyLeaf(pipeline, leaf), path, &options); !s) AddOnce(errors, s.error().message);
  }
}

}  // namespace

std::vector<std::string> CheckRunConfigFile(const std::filesystem::path& path) {
  const std::string file = path.string();
  YAML::Node root;
  try {
    root = YAML::LoadFile(file);
  } catch (const YAML::BadFile&) {
    return {file + ": cannot be read"};
  } catch (const YAML::Exception& e) {
    return {file + ": not valid YAML (line " + std::to_string(e.mark.line + 1) + ")"};
  }
  if (!root.IsMap()) return {file + ": expected a mapping with capture:, run: and the other blocks"};
  std::vector<std::string> errors;
  const std::vector<std::string> blocks = {"capture", "camera", "targets", "run", "pipeline", "format"};
  for (const auto& entry : root) {
    const std::string key = YamlKeyText(entry.first);
    if (std::find(blocks.begin(), blocks.end(), key) == blocks.end()) {
      errors.push_back(file + ": " + key + ": is not a block of a run config (capture, camera, targets, run, pipeline)");
    }
  }
  CheckCaptureFields(root["capture"], file, &errors);
  if (root["camera"] && !root["targets"]) {
    errors.push_back(file + ": camera: is read only together with a targets: block (family, size_m)");
  } else if (root["targets"]) {
    if (auto info = ReadCameraAndTargets(path); !info) AddOnce(&errors, info.error().message);
  }
  RunConfig scratch;
  for (const std::string& error : ReadRunBlock(root["run"], file, &scratch)) AddOnce(&errors, error);
  CheckPipelineFields(root["pipeline"], path, &errors);
  if (auto whole = ReadRunConfig(path); !whole) AddOnce(&errors, whole.error().message);
  return errors;
}

}  // namespace tagsfm
