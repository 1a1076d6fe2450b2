// recording.yaml: parsing with errors that name the field, and writing.
#include <algorithm>
#include <sstream>

#include <yaml-cpp/yaml.h>

#include "tagsfm/capture/recording.h"
#include "tagsfm/capture/yaml_file.h"

namespace tagsfm {

const std::vector<std::string>& KnownTagFamilies() {
  static const std::vector<std::string> families{"tag16h5",          "tag25h9",        "tag36h10",
                                                 "tag36h11",         "tagCircle21h7",  "tagCircle49h12",
                                                 "tagCustom48h12",   "tagStandard41h12", "tagStandard52h13"};
  return families;
}

double TargetConfig::SizeOf(TagId id) const {
  const auto it = size_by_id.find(id);
  return it != size_by_id.end() ? it->second : size_m;
}

Status TargetConfig::Check() const {
  const auto& known = KnownTagFamilies();
  if (std::find(known.begin(), known.end(), family) == known.end()) {
    std::string list;
    for (const auto& f : known) list += (list.empty() ? "" : ", ") + f;
    return MakeError("targets.family: unknown tag family '" + family + "' (known: " + list + ")");
  }
  if (!(size_m > 0)) return MakeError("targets.size_m must be > 0 (got " + std::to_string(size_m) + ")");
  for (const auto& [id, size] : size_by_id) {
    if (!(size > 0)) return MakeError("targets.size_by_id." + std::to_string(id) + " must be > 0");
  }
  return Status::Ok();
}

namespace {

// The `camera:` and `targets:` blocks, shared by recording.yaml and the
// daemon's config file.
Result<RecordingInfo> ParseCameraAndTargets(const YAML::Node& root, const std::string& file) {
  RecordingInfo info;
  if (const YAML::Node cam = root["camera"]; cam && !cam.IsNull()) {
    const std::string where = file + ": camera.";
    CameraModel c;
    std::string model = "pinhole";
    Status s = ReadYamlField(cam, "width", where, &c.width, true);
    if (s) s = ReadYamlField(cam, "height", where, &c.height, true);
    if (s) s = ReadYamlField(cam, "fx", where, &c.fx, true);
    if (s) s = ReadYamlField(cam, "fy", where, &c.fy, true);
    if (s) s = ReadYamlField(cam, "cx", where, &c.cx, true);
    if (s) s = ReadYamlField(cam, "cy", where, &c.cy, true);
    if (s) s = ReadYamlField(cam, "distortion", where, &c.distortion, false);
    if (s) s = ReadYamlField(cam, "model", where, &model, false);
    if (!s) return s.error();
    if (model == "fisheye") {
      c.kind = CameraModel::Kind::kFisheye;
    } else if (model != "pinhole") {
      return MakeError(where + "model must be 'pinhole' or 'fisheye' (got '" + model + "')");
    }
    if (Status check = c.Check(); !check) return MakeError(file + ": " + check.error().message);
    info.camera = c;
  }

  const YAML::Node targets = root["targets"];
  if (!targets || !targets.IsMap()) return MakeError(file + ": targets is missing");
  const std::string where = file + ": targets.";
  Status s = ReadYamlField(targets, "family", where, &info.targets.family, true);
  if (s) s = ReadYamlField(targets, "size_m", where, &info.targets.size_m, true);
  if (s) s = ReadYamlField(targets, "size_by_id", where, &info.targets.size_by_id, false);
  if (s) s = ReadYamlField(targets, "map", where, &info.targets.map, false);
  if (!s) return s.error();
  if (Status check = info.targets.Check(); !check) return MakeError(file + ": " + check.error().message);
  return info;
}

}  // namespace

Result<RecordingInfo> ReadRecordingYaml(const std::filesystem::path& yaml_path) {
  const std::string file = yaml_path.string();
  auto root = LoadYamlFile(file);
  if (!root) return root.error();
  std::string format;
  if (Status s = ReadYamlField(*root, "format", file + ": ", &format, true); !s) return s.error();
  if (format != "tagsfm-recording/1") return MakeError(file + ": format must be 'tagsfm-recording/1' (got '" + format + "')");
  return ParseCameraAndTargets(*root, file);
}

Result<RecordingInfo> ReadCameraAndTargets(const std::filesystem::path& yaml_path) {
  const std::string file = yaml_path.string();
  auto root = LoadYamlFile(file);
  if (!root) return root.error();
  return ParseCameraAndTargets(*root, file);
}

std::string RecordingYamlText(const RecordingInfo& info) {
  YAML::Emitter out;
  out.SetDoublePrecision(17);
  out << YAML::BeginMap << YAML::Key << "format" << YAML::Value << "tagsfm-recording/1";
  if (info.camera) {
    const CameraModel& c = *info.camera;
    out << YAML::Key << "camera" << YAML::Value << YAML::BeginMap;
    out << YAML::Key << "width" << YAML::Value << c.width << YAML::Key << "height" << YAML::Value << c.height;
    out << YAML::Key << "fx" << YAML::Value << c.fx << YAML::Key << "fy" << YAML::Value << c.fy;
    out << YAML::Key << "cx" << YAML::Value << c.cx << YAML::Key << "cy" << YAML::Value << c.cy;
    out << YAML::Key << "distortion" << YAML::Value << YAML::Flow << c.distortion;
    if (c.kind == CameraModel::Kind::kFisheye) out << YAML::Key << "model" << YAML::Value << "fisheye";
    out << YAML::EndMap;
  }
  out << YAML::Key << "targets" << YAML::Value << YAML::BeginMap;
  out << YAML::Key << "family" << YAML::Value << info.targets.family;
  out << YAML::Key << "size_m" << YAML::Value << info.targets.size_m;
  if (!info.targets.size_by_id.empty()) {
    out << YAML::Key << "size_by_id" << YAML::Value << YAML::Flow << info.targets.size_by_id;
  }
  if (!info.targets.map.empty()) out << YAML::Key << "map" << YAML::Value << info.targets.map;
  out << YAML::EndMap << YAML::EndMap;
  return std::string(out.c_str()) + "\n";
}

}  // namespace tagsfm
