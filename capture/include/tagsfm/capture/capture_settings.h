#pragma once
// Camera settings for live capture, read from a firmware_config/*.yaml file
// (its `capture:` block). Photogrammetry wants a camera that does not change
// between frames: fixed focus (refocusing changes the intrinsics) and fixed
// exposure (auto exposure changes motion blur and noise); Check() enforces
// what is wrong, Warnings() says what is risky.
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "tagsfm/core/result.h"

namespace tagsfm {

struct CaptureSettings {
  std::string source = "v4l2:/dev/video0";  // camera URI (see frame_source.h)
  int width = 1280;
  int height = 720;
  double fps = 30.0;
  bool colour = false;        // grey frames are what detection needs, and half the disk
  int exposure_us = 0;        // 0: leave the camera's automatic exposure on
  int gain = -1;              // -1: leave as is
  bool autofocus = false;     // off: refocusing would change the intrinsics mid-capture
  int focus_absolute = -1;    // -1: leave as is
  int buffers = 4;            // V4L2 driver buffers
  std::string pixel_format;   // V4L2 FourCC (GREY, YUYV, UYVY, MJPG, BGR3, RGB3); empty: the best the camera offers
  std::optional<int> brightness;  // absent: leave as is (ranges differ by camera, some go below 0)
  // A camera that vanishes mid-capture (unplugged, driver reset): 0 ends the
  // capture at once with an error; > 0 waits up to this long for it to come
  // back and goes on (the frames in between are lost, the recording is not).
  double reconnect_wait_s = 0.0;

  Status Check() const;
  std::vector<std::string> Warnings() const;
};

// Reads the `capture:` block of a config file; absent fields keep defaults.
Result<CaptureSettings> ReadCaptureSettings(const std::filesystem::path& yaml_path);

}  // namespace tagsfm
