#pragma once
#include <cstdint>
#include <string>

#include <opencv2/core.hpp>

#include "tagsfm/core/csv_formats.h"

namespace tagsfm {

// One image from a camera or a recording, as it passes between stages.
struct Frame {
  FrameId index = 0;
  std::int64_t timestamp_ns = 0;
  cv::Mat image;       // as captured or stored: 8 or 16 bit, grey or colour
  cv::Mat gray;        // 8-bit single channel, what detection works on
  std::string source;  // file path or camera URI, for messages
};

// 8-bit grey view of any supported image (16-bit is scaled by 1/257).
cv::Mat ToGray8(const cv::Mat& image);

}  // namespace tagsfm
