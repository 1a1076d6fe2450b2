#include "tagsfm/capture/capture_settings.h"

#include <yaml-cpp/yaml.h>

#include "tagsfm/capture/pixel_decode.h"
#include "tagsfm/capture/yaml_file.h"

namespace tagsfm {

Status CaptureSettings::Check() const {
  if (source.find(':') == std::string::npos) return MakeError("capture.source must be a URI such as v4l2:/dev/video0 (got '" + source + "')");
  if (width <= 0 || height <= 0) return MakeError("capture.width and capture.height must be > 0");
  if (!(fps > 0) || fps > 1000) return MakeError("capture.fps must be in (0, 1000] (got " + std::to_string(fps) + ")");
  if (exposure_us < 0) return MakeError("capture.exposure_us must be >= 0 (0 = automatic)");
  if (gain < -1) return MakeError("capture.gain must be >= 0, or -1 to leave it");
  if (focus_absolute < -1) return MakeError("capture.focus_absolute must be >= 0, or -1 to leave it");
  if (buffers < 2 || buffers > 32) return MakeError("capture.buffers must be in 2..32 (got " + std::to_string(buffers) + ")");
  if (!pixel_format.empty() && !CanDecodePixelFormat(FourCc(pixel_format))) {
    return MakeError("capture.pixel_format must be one of GREY, YUYV, UYVY, MJPG, BGR3, RGB3 (got '" + pixel_format + "')");
  }
  if (!(reconnect_wait_s >= 0) || reconnect_wait_s > 3600) {
    return MakeError("capture.reconnect_wait_s must be in [0, 3600] seconds (got " + std::to_string(reconnect_wait_s) + ")");
  }
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
  Result<YAML::Node> root = LoadYamlFile(file, /*allow_empty=*/true);
  if (!root) return root.error();
  CaptureSettings settings;
  const YAML::Node node = (*root)["capture"];
  if (!node) return settings;
  if (!node.IsMap()) return MakeError(file + ": capture must be a mapping");
  const std::string where = file + ": capture.";
  Status s = ReadYamlField(node, "source", where, &settings.source);
  if (s) s = ReadYamlField(node, "width", where, &settings.width);
  if (s) s = ReadYamlField(node, "height", where, &settings.height);
  if (s) s = ReadYamlField(node, "fps", where, &settings.fps);
  if (s) s = ReadYamlField(node, "colour", where, &settings.colour);
  if (s) s = ReadYamlField(node, "exposure_us", where, &settings.exposure_us);
  if (s) s = ReadYamlField(node, "gain", where, &settings.gain);
  if (s) s = ReadYamlField(node, "autofocus", where, &settings.autofocus);
  if (s) s = ReadYamlField(node, "focus_absolute", where, &settings.focus_absolute);
  if (s) s = ReadYamlField(node, "buffers", where, &settings.buffers);
  if (s) s = ReadYamlField(node, "pixel_format", where, &settings.pixel_format);
  if (s) s = ReadYamlField(node, "reconnect_wait_s", where, &settings.reconnect_wait_s);
  if (s && node["brightness"]) {
    int brightness = 0;
    s = ReadYamlField(node, "brightness", where, &brightness);
    settings.brightness = brightness;
  }
  if (!s) return s.error();
  if (Status check = settings.Check(); !check) return MakeError(file + ": " + check.error().message);
  return settings;
}

}  // namespace tagsfm
