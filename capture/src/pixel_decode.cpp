#include "tagsfm/capture/pixel_decode.h"

#include <linux/videodev2.h>

#include <algorithm>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "tagsfm/capture/image_header.h"

namespace tagsfm {
namespace {

int BytesPerPixel(std::uint32_t fourcc) {
  switch (fourcc) {
    case V4L2_PIX_FMT_GREY: return 1;
    case V4L2_PIX_FMT_YUYV:
    case V4L2_PIX_FMT_UYVY: return 2;
    case V4L2_PIX_FMT_BGR24:
    case V4L2_PIX_FMT_RGB24: return 3;
    default: return 0;  // compressed
  }
}

Result<DecodedPixels> DecodeJpeg(const PixelLayout& layout, const std::uint8_t* data, size_t bytes_used, bool colour) {
  // A header over the driver's buffer: imdecode reads it in place.
  // A header that claims another size is refused before the decoder
  // allocates what it claims.
  const auto claimed = EncodedImageSize(data, bytes_used);
  if (claimed && (claimed->width != layout.width || claimed->height != layout.height)) {
    return MakeError("MJPG frame header says " + std::to_string(claimed->width) + "x" + std::to_string(claimed->height) +
                     ", the negotiated size is " + std::to_string(layout.width) + "x" + std::to_string(layout.height));
  }
  const cv::Mat encoded(1, static_cast<int>(bytes_used), CV_8UC1, const_cast<std::uint8_t*>(data));
  DecodedPixels out;
  try {
    out.image = cv::imdecode(encoded, colour ? cv::IMREAD_COLOR : cv::IMREAD_GRAYSCALE);
  } catch (const cv::Exception&) {
    out.image.release();
  }
  if (out.image.empty()) return MakeError("MJPG data (" + std::to_string(bytes_used) + " bytes) does not decode");
  if (out.image.cols != layout.width || out.image.rows != layout.height) {
    return MakeError("MJPG frame is " + std::to_string(out.image.cols) + "x" + std::to_string(out.image.rows) +
                     ", the negotiated size is " + std::to_string(layout.width) + "x" + std::to_string(layout.height));
  }
  if (colour) {
    cv::cvtColor(out.image, out.gray, cv::COLOR_BGR2GRAY);
  } else {
    out.gray = out.image;
  }
  return out;
}

}  // namespace

std::uint32_t FourCc(const std::string& name) {
  if (name.size() != 4) return 0;
  return v4l2_fourcc(name[0], name[1], name[2], name[3]);
}

std::string FourCcName(std::uint32_t fourcc) {
  std::string name;
  for (int i = 0; i < 4; ++i) {
    const char c = static_cast<char>((fourcc >> (8 * i)) & 0xff);
    name += (c >= 32 && c < 127) ? c : '?';
  }
  return name;
}

bool CanDecodePixelFormat(std::uint32_t fourcc) {
  return BytesPerPixel(fourcc) > 0 || fourcc == V4L2_PIX_FMT_MJPEG;
}

const std::vector<std::string>& DecodablePixelFormats(bool colour) {
  // Grey: the sensor's own luma first, JPEG (lossy, costly) late.
  static const std::vector<std::string> grey = {"GREY", "YUYV", "UYVY", "MJPG", "BGR3", "RGB3"};
  static const std::vector<std::string> rgb = {"BGR3", "RGB3", "YUYV", "UYVY", "MJPG", "GREY"};
  return colour ? rgb : grey;
}

Result<std::uint32_t> ChoosePixelFormat(const std::vector<std::uint32_t>& offered, const std::string& wanted,
                                        bool colour) {
  std::string offered_names;
  for (std::uint32_t f : offered) offered_names += (offered_names.empty() ? "" : ", ") + FourCcName(f);
  const auto is_offered = [&](std::uint32_t f) { return std::find(offered.begin(), offered.end(), f) != offered.end(); };
  if (!wanted.empty()) {
    const std::uint32_t f = FourCc(wanted);
    if (!CanDecodePixelFormat(f)) return MakeError("capture.pixel_format '" + wanted + "' is not one tagsfm decodes");
    if (!offered.empty() && !is_offered(f)) {
      return MakeError("does not offer pixel format " + wanted + " (it offers " + offered_names + ")");
    }
    return f;
  }
  if (offered.empty()) return FourCc(DecodablePixelFormats(colour).front());  // the driver lists nothing: try
  for (const std::string& name : DecodablePixelFormats(colour)) {
    if (is_offered(FourCc(name))) return FourCc(name);
  }
  return MakeError("offers no pixel format tagsfm decodes (it offers " + offered_names + "; tagsfm reads GREY, YUYV, UYVY, MJPG, BGR3, RGB3)");
}

Result<DecodedPixels> DecodePixels(const PixelLayout& layout, const std::uint8_t* data, size_t bytes_used, bool colour) {
  if (layout.fourcc == V4L2_PIX_FMT_MJPEG) return DecodeJpeg(layout, data, bytes_used, colour);
  const int bpp = BytesPerPixel(layout.fourcc);
  if (bpp == 0) return MakeError("pixel format " + FourCcName(layout.fourcc) + " is not one tagsfm decodes");
  const size_t stride = layout.bytes_per_line > 0 ? static_cast<size_t>(layout.bytes_per_line)
                                                  : static_cast<size_t>(layout.width) * static_cast<size_t>(bpp);
  const size_t needed = stride * static_cast<size_t>(layout.height - 1) + static_cast<size_t>(layout.width) * static_cast<size_t>(bpp);
  if (layout.width <= 0 || layout.height <= 0 || bytes_used < needed) {
    return MakeError("buffer holds " + std::to_string(bytes_used) + " bytes, a " + std::to_string(layout.width) + "x" +
                     std::to_string(layout.height) + " " + FourCcName(layout.fourcc) + " frame needs " + std::to_string(needed));
  }
  void* pixels = const_cast<std::uint8_t*>(data);
  DecodedPixels out;
  switch (layout.fourcc) {
    case V4L2_PIX_FMT_GREY:
      out.image = cv::Mat(layout.height, layout.width, CV_8UC1, pixels, stride).clone();
      out.gray = out.image;
      return out;
    case V4L2_PIX_FMT_YUYV:
    case V4L2_PIX_FMT_UYVY: {
      // Two bytes per pixel, Y first (YUYV) or second (UYVY): a two-channel
      // view whose Y channel is copied out in one pass.
      const cv::Mat view(layout.height, layout.width, CV_8UC2, pixels, stride);
      const bool yuyv = layout.fourcc == V4L2_PIX_FMT_YUYV;
      cv::extractChannel(view, out.gray, yuyv ? 0 : 1);
      if (colour) {
        cv::cvtColor(view, out.image, yuyv ? cv::COLOR_YUV2BGR_YUYV : cv::COLOR_YUV2BGR_UYVY);
      } else {
        out.image = out.gray;
      }
      return out;
    }
    default: {
      const cv::Mat view(layout.height, layout.width, CV_8UC3, pixels, stride);
      if (layout.fourcc == V4L2_PIX_FMT_RGB24) {
        cv::cvtColor(view, out.image, cv::COLOR_RGB2BGR);
      } else {
        out.image = view.clone();
      }
      cv::cvtColor(out.image, out.gray, cv::COLOR_BGR2GRAY);
      if (!colour) out.image = out.gray;
      return out;
    }
  }
}

}  // namespace tagsfm
