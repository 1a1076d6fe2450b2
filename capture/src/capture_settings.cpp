#include "tagsfm/capture/capture_settings.h"

#include <yaml-cpp/yaml.h>

namespace tagsfm {
namespace {

template <class T>
Status ReadOptional(const YAML::Node& node, const std::string& key, const std::string& where, T* out) {
  const YAML::Node value = node[key];
  if (!value) return Status::Ok();
  try {
    *out = value.as<T>();
  } catch (const YAML::Exception&) {
    return MakeError(where + key + " has the wrong type: '" + YAML::Dump(value) + "'");
  }
  return Status::Ok();
}

}  // namespace

Status CaptureSettings::Check() const {
  if (source.find(':') == std::string::npos) return MakeError("capture.source must be a URI such as v4l2:/dev/video0 (got '" + source + "')");
  if (width <= 0 || height <= 0) return MakeError("capture.width and capture.height must be > 0");
  if (!(fps > 0) || fps > 1000) return MakeError("capture.fps must be in (0, 1000] (got " + std::to_string(fps) + ")");
  if (exposure_us < 0) return MakeError("capture.exposure_us must be >= 0 (0 = automatic)");
  if (gain < -1) return MakeError("capture.gain must be >= 0, or -1 to leave it");
  if (focus_absolute < -1) return MakeError("capture.focus_absolute must be >= 0, or -1 to leave it");
  if (buffers < 2 || buffers > 32) return MakeError("capture.buffers must be in 2..32 (got " + std::to_string(buffers) + ")");
  return Status::Ok();
}

std::vector<std::string> CaptureSettings::Warnings() const {
  std::vector<std::string> warnings;
  if (autofocus) warnings.push_back("capture.autofocus is on: refocusing changes the focal length and spoils the calibration");
  if (exposure_us == 0) warnings.push_back("capture.exposure_us is 0 (automatic): set a fixed, short exposure to keep motion blur low");
  if (exposure_us > 0 && fps > 0 && exposure_us > 1e6 / fps) {
    warnings.push_back("capture.exposure_us is longer than one frame at capture.fps: the frame rate will drop");
  }
  return warnings;
}

Result<CaptureSettings> ReadCaptureSettings(const std::filesystem::path& yaml_path) {
  const std::string file = yaml_path.string();
  YAML::Node root;
  try {
    root = YAML::LoadFile(file);
  } catch (const YAML::BadFile&) {
    return MakeError(file + ": cannot open");
  } catch (const YAML::Exception& e) {
    return MakeError(file + ": not valid YAML (line " + std::to_string(e.mark.line + 1) + ")");
  }
  CaptureSettings settings;
  const YAML::Node node = root["capture"];
  if (!node) return settings;
  if (!node.IsMap()) return MakeError(file + ": capture must be a mapping");
  const std::string where = file + ": capture.";
  Status s = ReadOptional(node, "source", where, &settings.source);
  if (s) s = ReadOptional(node, "width", where, &settings.width);
  if (s) s = ReadOptional(node, "height", where, &settings.height);
  if (s) s = ReadOptional(node, "fps", where, &settings.fps);
  if (s) s = ReadOptional(node, "colour", where, &settings.colour);
  if (s) s = ReadOptional(node, "exposure_us", where, &settings.exposure_us);
  if (s) s = ReadOptional(node, "gain", where, &settings.gain);
  if (s) s = ReadOptional(node, "autofocus", where, &settings.autofocus);
  if (s) s = ReadOptional(node, "focus_absolute", where, &settings.focus_absolute);
  if (s) s = ReadOptional(node, "buffers", where, &settings.buffers);
  if (!s) return s.error();
  if (Status check = settings.Check(); !check) return MakeError(file + ": " + check.error().message);
  return settings;
}

}  // namespace tagsfm
