#pragma once
// A camera's own pixel formats, chosen and decoded by tagsfm (not by
// libv4l2's conversion): the grey image detection needs is taken the
// cheapest way each format allows.
//   GREY        one copy out of the driver's buffer; gray shares it
//   YUYV, UYVY  the Y samples in one pass (no colour conversion)
//   MJPG        decoded straight from the buffer by libjpeg-turbo (OpenCV
//               imdecode); grey asks the decoder for luma only
//   BGR3, RGB3  one copy (+ channel swap), grey by conversion
#include <cstdint>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "tagsfm/core/result.h"

namespace tagsfm {

std::uint32_t FourCc(const std::string& name);     // "YUYV" -> V4L2_PIX_FMT_YUYV
std::string FourCcName(std::uint32_t fourcc);      // and back
bool CanDecodePixelFormat(std::uint32_t fourcc);
// The formats tagsfm decodes, best first for grey or for colour frames.
const std::vector<std::string>& DecodablePixelFormats(bool colour);

// The format to ask for: `wanted` if given (it must be offered, when the
// device lists any), else the first of DecodablePixelFormats(colour) offered.
Result<std::uint32_t> ChoosePixelFormat(const std::vector<std::uint32_t>& offered, const std::string& wanted,
                                        bool colour);

struct PixelLayout {
  std::uint32_t fourcc = 0;
  int width = 0;
  int height = 0;
  int bytes_per_line = 0;  // 0: tightly packed
};

struct DecodedPixels {
  cv::Mat image;  // what is recorded: grey, or BGR when colour is asked and the format has it
  cv::Mat gray;   // 8-bit grey, shares image's data when image is grey
};

// Decodes `bytes_used` bytes of one buffer; the result owns its data (the
// buffer can be handed back to the driver at once). Errors say what is wrong
// with the data (short buffer, undecodable or wrong-sized JPEG).
Result<DecodedPixels> DecodePixels(const PixelLayout& layout, const std::uint8_t* data, size_t bytes_used,
                                   bool colour);

}  // namespace tagsfm
