#pragma once
// Camera settings for live capture, read from a firmware_config/*.yaml file
// (its `capture:` block). Photogrammetry wants a camera that does not change
// between frames: fixed focus (refocusing changes the intrinsics) and fixed
// exposure (auto exposure changes motion blur and noise); Check() enforces
// what is wrong, Warnings() says what is risky.
#include <filesystem>
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

  Status Check() const;
  std::vector<std::string> Warnings() const;
};

// Reads the `capture:` block of a config file; absent fields keep defaults.
Result<CaptureSettings> ReadCaptureSettings(const std::filesystem::path& yaml_path);

}  // namespace tagsfm
