#include "v4l2_controls.h"

#include <linux/videodev2.h>

#include <algorithm>
#include <cstring>

namespace tagsfm {
namespace {

struct ControlRequest {
  unsigned id;
  int value;
  std::string setting;   // the capture.* field, for messages
  std::string name;      // what the control is called
  bool silent_if_absent; // a helper control (auto modes) many cameras lack
};

void ApplyOne(V4l2Device& device, const ControlRequest& request, const std::string& uri, std::set<std::string>& warned,
              std::vector<std::string>& warnings) {
  const auto warn = [&](const std::string& why) {
    if (warned.insert(request.setting + "/" + request.name).second) warnings.push_back(uri + ": " + why);
  };
  v4l2_queryctrl query{};
  query.id = request.id;
  if (device.Ioctl(VIDIOC_QUERYCTRL, &query) != 0 || (query.flags & V4L2_CTRL_FLAG_DISABLED)) {
    if (request.silent_if_absent) return;
    if (request.id == V4L2_CID_FOCUS_AUTO && request.value == 0) {
      warn("has no autofocus control (fixed focus?): capture.autofocus: false has nothing to switch off");
    } else {
      warn("has no " + request.name + " control: " + request.setting + " is ignored");
    }
    return;
  }
  if (request.value < query.minimum || request.value > query.maximum) {
    warn(request.setting + " asks " + request.name + " " + std::to_string(request.value) + ", outside the camera's range " +
         std::to_string(query.minimum) + ".." + std::to_string(query.maximum) + ": left unchanged");
    return;
  }
  v4l2_control control{};
  control.id = request.id;
  control.value = request.value;
  if (const int error = device.Ioctl(VIDIOC_S_CTRL, &control); error != 0) {
    warn("cannot set " + request.name + " to " + std::to_string(request.value) + " for " + request.setting + " (" +
         std::strerror(error) + ")");
    return;
  }
  v4l2_control applied{};
  applied.id = request.id;
  if (device.Ioctl(VIDIOC_G_CTRL, &applied) == 0 && applied.value != request.value) {
    warn(request.setting + " asked " + request.name + " " + std::to_string(request.value) + ", the camera kept " +
         std::to_string(applied.value));
  }
}

std::vector<ControlRequest> Requests(const CaptureSettings& s) {
  std::vector<ControlRequest> requests;
  requests.push_back({V4L2_CID_FOCUS_AUTO, s.autofocus ? 1 : 0, "capture.autofocus", "autofocus", false});
  if (s.focus_absolute >= 0) {
    requests.push_back({V4L2_CID_FOCUS_ABSOLUTE, s.focus_absolute, "capture.focus_absolute", "absolute focus", false});
  }
  if (s.exposure_us > 0) {
    // Manual mode first, else the camera ignores the exposure time; V4L2's
    // absolute exposure counts 100 µs units.
    requests.push_back({V4L2_CID_EXPOSURE_AUTO, V4L2_EXPOSURE_MANUAL, "capture.exposure_us", "manual exposure mode", true});
    requests.push_back({V4L2_CID_EXPOSURE_ABSOLUTE, std::max(1, s.exposure_us / 100), "capture.exposure_us",
                        "absolute exposure", false});
  }
  if (s.gain >= 0) {
    requests.push_back({V4L2_CID_AUTOGAIN, 0, "capture.gain", "automatic gain", true});
    requests.push_back({V4L2_CID_GAIN, s.gain, "capture.gain", "gain", false});
  }
  if (s.brightness) requests.push_back({V4L2_CID_BRIGHTNESS, *s.brightness, "capture.brightness", "brightness", false});
  return requests;
}

}  // namespace

void ApplyV4l2Controls(V4l2Device& device, const CaptureSettings& settings, const std::string& uri,
                       std::set<std::string>& warned, std::vector<std::string>& warnings) {
  for (const ControlRequest& request : Requests(settings)) ApplyOne(device, request, uri, warned, warnings);
}

}  // namespace tagsfm
