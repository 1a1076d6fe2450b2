#include "tagsfm/capture/capture_settings.h"

#include <gtest/gtest.h>

#include "recording_test_util.h"
#include "test_paths.h"

namespace tagsfm {
namespace {

TEST(CaptureSettings, ReadsPixelFormatBrightnessAndReconnectWait) {
  testing::TempDir tmp;
  const auto path = tmp.path() / "cam.yaml";
  testing::WriteTextFile(path, "capture:\n  pixel_format: MJPG\n  brightness: -12\n  reconnect_wait_s: 30\n");
  auto settings = ReadCaptureSettings(path);
  ASSERT_TRUE(settings) << settings.error().message;
  EXPECT_EQ(settings->pixel_format, "MJPG");
  ASSERT_TRUE(settings->brightness.has_value());
  EXPECT_EQ(*settings->brightness, -12);
  EXPECT_EQ(settings->reconnect_wait_s, 30.0);

  testing::WriteTextFile(path, "capture:\n  pixel_format: H264\n");
  settings = ReadCaptureSettings(path);
  ASSERT_FALSE(settings);
  EXPECT_NE(settings.error().message.find("capture.pixel_format must be one of GREY, YUYV, UYVY, MJPG, BGR3, RGB3 (got 'H264')"),
            std::string::npos)
      << settings.error().message;

  testing::WriteTextFile(path, "capture:\n  reconnect_wait_s: -1\n");
  settings = ReadCaptureSettings(path);
  ASSERT_FALSE(settings);
  EXPECT_NE(settings.error().message.find("capture.reconnect_wait_s"), std::string::npos) << settings.error().message;

  testing::WriteTextFile(path, "capture:\n  brightness: high\n");
  settings = ReadCaptureSettings(path);
  ASSERT_FALSE(settings);
  EXPECT_NE(settings.error().message.find("capture.brightness has the wrong type"), std::string::npos)
      << settings.error().message;
}

}  // namespace
}  // namespace tagsfm
