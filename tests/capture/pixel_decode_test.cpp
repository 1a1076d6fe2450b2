#include "tagsfm/capture/pixel_decode.h"

#include <linux/videodev2.h>

#include <gtest/gtest.h>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

namespace tagsfm {
namespace {

TEST(PixelDecode, ChoosesTheCheapestGreyAndTheBestColourFormatOffered) {
  const std::vector<std::uint32_t> webcam = {V4L2_PIX_FMT_MJPEG, V4L2_PIX_FMT_YUYV};
  EXPECT_EQ(*ChoosePixelFormat(webcam, "", false), static_cast<std::uint32_t>(V4L2_PIX_FMT_YUYV));
  EXPECT_EQ(*ChoosePixelFormat(webcam, "MJPG", false), static_cast<std::uint32_t>(V4L2_PIX_FMT_MJPEG));
  const std::vector<std::uint32_t> mono = {V4L2_PIX_FMT_YUYV, V4L2_PIX_FMT_GREY, V4L2_PIX_FMT_BGR24};
  EXPECT_EQ(*ChoosePixelFormat(mono, "", false), static_cast<std::uint32_t>(V4L2_PIX_FMT_GREY));
  EXPECT_EQ(*ChoosePixelFormat(mono, "", true), static_cast<std::uint32_t>(V4L2_PIX_FMT_BGR24));
  EXPECT_EQ(*ChoosePixelFormat({V4L2_PIX_FMT_MJPEG}, "", true), static_cast<std::uint32_t>(V4L2_PIX_FMT_MJPEG));
  auto unknown = ChoosePixelFormat(webcam, "H264", false);
  ASSERT_FALSE(unknown);
  EXPECT_EQ(unknown.error().message, "capture.pixel_format 'H264' is not one tagsfm decodes");
  EXPECT_EQ(FourCcName(FourCc("YUYV")), "YUYV");
}

TEST(PixelDecode, UyvyGivesItsLumaAsGreyAndConvertsToColour) {
  // 4x2 UYVY with 4 bytes of padding per row.
  const int w = 4, h = 2, stride = 12;
  std::vector<std::uint8_t> bytes(stride * h, 0xEE);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      bytes[y * stride + 2 * x] = 128;                                   // U/V: no colour
      bytes[y * stride + 2 * x + 1] = static_cast<std::uint8_t>(50 + 20 * x + 100 * y);  // Y
    }
  const PixelLayout layout{V4L2_PIX_FMT_UYVY, w, h, stride};
  auto grey = DecodePixels(layout, bytes.data(), bytes.size(), false);
  ASSERT_TRUE(grey);
  EXPECT_EQ(grey->gray.at<std::uint8_t>(1, 3), 210);
  auto colour = DecodePixels(layout, bytes.data(), bytes.size(), true);
  ASSERT_TRUE(colour);
  ASSERT_EQ(colour->image.type(), CV_8UC3);
  // Neutral chroma: B = G = R, within the rounding of the video-range conversion.
  const cv::Vec3b px = colour->image.at<cv::Vec3b>(1, 3);
  EXPECT_LE(std::abs(px[0] - px[2]), 1);
  EXPECT_EQ(colour->gray.at<std::uint8_t>(1, 3), 210) << "grey is the sensor's luma, not a re-conversion";
}

TEST(PixelDecode, ShortBuffersAndWrongSizedJpegsAreErrorsNotCrashes) {
  std::vector<std::uint8_t> bytes(100, 0);
  auto short_grey = DecodePixels({V4L2_PIX_FMT_GREY, 64, 48, 64}, bytes.data(), bytes.size(), false);
  ASSERT_FALSE(short_grey);
  EXPECT_EQ(short_grey.error().message, "buffer holds 100 bytes, a 64x48 GREY frame needs 3072");
  std::vector<std::uint8_t> jpeg;
  cv::imencode(".jpg", cv::Mat(32, 32, CV_8UC1, cv::Scalar(90)), jpeg);
  auto wrong = DecodePixels({V4L2_PIX_FMT_MJPEG, 64, 48, 0}, jpeg.data(), jpeg.size(), false);
  ASSERT_FALSE(wrong);
  // Refused from its header, before the decoder allocates what it claims.
  EXPECT_EQ(wrong.error().message, "MJPG frame header says 32x32, the negotiated size is 64x48");
  auto cut = DecodePixels({V4L2_PIX_FMT_MJPEG, 32, 32, 0}, jpeg.data(), 20, false);
  EXPECT_FALSE(cut);
}

}  // namespace
}  // namespace tagsfm
