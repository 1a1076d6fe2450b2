#pragma once
// Small recordings written by hand for the capture tests.
#include <filesystem>
#include <fstream>
#include <string>

#include <opencv2/imgcodecs.hpp>

namespace tagsfm::testing {

inline const char* kMinimalYaml =
    "format: tagsfm-recording/1\n"
    "camera:\n  width: 64\n  height: 48\n  fx: 50.0\n  fy: 50.0\n  cx: 32.0\n  cy: 24.0\n"
    "  distortion: [0, 0, 0, 0, 0]\n"
    "targets:\n  family: tag36h11\n  size_m: 0.08\n  size_by_id: {3: 0.04}\n";

inline void WriteTextFile(const std::filesystem::path& path, const std::string& text) {
  std::ofstream(path, std::ios::binary) << text;
}

// A 64x48 gradient image whose pixels depend on `seed`.
inline cv::Mat TestImage(int seed, int type = CV_8UC1) {
  cv::Mat image(48, 64, type);
  const int channels = image.channels();
  const bool wide = image.depth() == CV_16U;
  for (int y = 0; y < image.rows; ++y) {
    for (int x = 0; x < image.cols; ++x) {
      for (int c = 0; c < channels; ++c) {
        const int v = (x * 3 + y * 5 + seed * 7 + c * 11) % 256;
        if (wide) {
          image.ptr<uint16_t>(y)[x * channels + c] = static_cast<uint16_t>(v * 257);
        } else {
          image.ptr<uint8_t>(y)[x * channels + c] = static_cast<uint8_t>(v);
        }
      }
    }
  }
  return image;
}

}  // namespace tagsfm::testing
