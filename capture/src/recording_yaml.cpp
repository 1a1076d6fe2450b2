// recording.yaml: parsing with errors that name the field, and writing.
#include <algorithm>
#include <sstream>

#include <yaml-cpp/yaml.h>

#include "tagsfm/capture/recording.h"
#include "tagsfm/capture/yaml_file.h"
#include "tagsfm/core/file_util.h"

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

// "12" (tag 12's centre) or "12:3" (its corner 3).
Result<ScaleBarPoint> ParseScaleBarPoint(const std::string& text, const std::string& where) {
  ScaleBarPoint p;
  const size_t colon = text.find(':');
  long long id = 0, corner = -1;
  if (!ParseInt64(text.substr(0, colon), &id) ||
      (colon != std::string::npos && (!ParseInt64(text.substr(colon + 1), &corner) || corner < 0 || corner > 3))) {
    return MakeError(where + ": '" + text + "' is not a target point (a tag id, or ID:CORNER with corner 0-3)");
  }
  p.tag = static_cast<TagId>(id);
  p.corner = static_cast<int>(corner);
  return p;
}

// targets.scale_bars: a list of {a, b, length_m, sigma_m}.
Status ParseScaleBars(const YAML::Node& targets, const std::string& where, std::vector<ScaleBar>* bars) {
  const YAML::Node list = targets["scale_bars"];
  if (!list || list.IsNull()) return Status::Ok();
  if (!list.IsSequence()) return MakeError(where + "scale_bars must be a list of {a, b, length_m, sigma_m}");
  for (size_t i = 0; i < list.size(); ++i) {
    const std::string at = where + "scale_bars[" + std::to_string(i) + "].";
    if (!list[i].IsMap()) return MakeError(at.substr(0, at.size() - 1) + " must be a map {a, b, length_m, sigma_m}");
    std::string a, b;
    ScaleBar bar;
    Status s = ReadYamlField(list[i], "a", at, &a, true);
    if (s) s = ReadYamlField(list[i], "b", at, &b, true);
    if (s) s = ReadYamlField(list[i], "length_m", at, &bar.length_m, true);
    if (s) s = ReadYamlField(list[i], "sigma_m", at, &bar.sigma_m, true);
    if (!s) return s;
    auto pa = ParseScaleBarPoint(a, at + "a");
    if (!pa) return pa.error();
    auto pb = ParseScaleBarPoint(b, at + "b");
    if (!pb) return pb.error();
    bar.a = *pa;
    bar.b = *pb;
    if (!(bar.length_m > 0)) return MakeError(at + "length_m must be > 0");
    if (!(bar.sigma_m > 0)) return MakeError(at + "sigma_m must be > 0 (the certificate's 1-sigma)");
    if (bar.a.tag == bar.b.tag && bar.a.corner == bar.b.corner) return MakeError(at + "b: the same point as a");
    bars->push_back(bar);
  }
  return Status::Ok();
}

std::string ScaleBarPointText(const ScaleBarPoint& p) {
  return p.corner < 0 ? std::to_string(p.tag) : std::to_string(p.tag) + ":" + std::to_string(p.corner);
}

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
  if (s) s = ParseScaleBars(targets, where, &info.targets.scale_bars);
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
  if (!info.targets.scale_bars.empty()) {
    out << YAML::Key << "scale_bars" << YAML::Value << YAML::BeginSeq;
    for (const ScaleBar& bar : info.targets.scale_bars) {
      out << YAML::Flow << YAML::BeginMap << YAML::Key << "a" << YAML::Value << ScaleBarPointText(bar.a) << YAML::Key
          << "b" << YAML::Value << ScaleBarPointText(bar.b) << YAML::Key << "length_m" << YAML::Value << bar.length_m
          << YAML::Key << "sigma_m" << YAML::Value << bar.sigma_m << YAML::EndMap;
    }
    out << YAML::EndSeq;
  }
  out << YAML::EndMap << YAML::EndMap;
  return std::string(out.c_str()) + "\n";
}

}  // namespace tagsfm
