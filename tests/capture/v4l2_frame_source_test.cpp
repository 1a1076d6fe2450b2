// The V4L2 streaming logic against a scripted camera (fake_v4l2_device.h).
#include <gtest/gtest.h>

#include <atomic>
#include <cstring>

#include <opencv2/imgcodecs.hpp>

#include "fake_v4l2_device.h"
#include "recording_test_util.h"
#include "tagsfm/capture/recorder.h"
#include "tagsfm/capture/v4l2_device.h"
#include "test_paths.h"

namespace tagsfm {
namespace {

using testing::FakeCamera;
using testing::FakeStep;
using testing::FakeV4l2Device;

constexpr const char* kDevice = "/dev/video7";

// Frame n of a 64x48 GREY camera: a gradient whose pixels depend on n.
std::vector<std::uint8_t> GreyBytes(const FakeCamera& camera, int n) {
  std::vector<std::uint8_t> bytes;
  for (int y = 0; y < camera.height; ++y) {
    for (int x = 0; x < camera.width; ++x) bytes.push_back(static_cast<std::uint8_t>((x * 3 + y * 5 + n * 7) % 256));
    bytes.insert(bytes.end(), static_cast<size_t>(camera.row_padding), 0xEE);
  }
  return bytes;
}

std::shared_ptr<FakeCamera> GreyCamera(int frames) {
  auto camera = std::make_shared<FakeCamera>();
  camera->frame_bytes = [c = camera.get()](int n) { return GreyBytes(*c, n); };
  camera->script.assign(static_cast<size_t>(frames), FakeStep{});
  return camera;
}

CaptureSettings Settings() {
  CaptureSettings settings;
  settings.source = std::string("v4l2:") + kDevice;
  settings.width = 64;
  settings.height = 48;
  return settings;
}

Result<std::unique_ptr<FrameSource>> Open(const std::shared_ptr<FakeCamera>& camera, const CaptureSettings& settings) {
  return OpenV4l2FrameSource(kDevice, std::make_unique<FakeV4l2Device>(camera), settings);
}

bool Contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

std::string Joined(const std::vector<std::string>& lines) {
  std::string all;
  for (const auto& line : lines) all += line + "\n";
  return all;
}

TEST(V4l2FrameSource, CyclesItsBuffersAndDeliversEveryFrameOnceInOrder) {
  auto camera = GreyCamera(20);
  camera->row_padding = 8;  // bytesperline > width: the stride must be honoured
  {
    auto source = Open(camera, Settings());
    ASSERT_TRUE(source) << source.error().message;
    for (int n = 0; n < 20; ++n) {
      auto frame = (*source)->Next();
      ASSERT_TRUE(frame && frame->has_value()) << n;
      const Frame& f = **frame;
      EXPECT_EQ(f.index, static_cast<FrameId>(n));
      EXPECT_EQ(f.timestamp_ns, 1'000'000'000LL + 33'333'000LL * n);
      ASSERT_EQ(f.image.size(), cv::Size(64, 48));
      // The frame's own pixels, not a stale buffer's.
      cv::Mat expected(48, 64, CV_8UC1);
      for (int y = 0; y < 48; ++y)
        for (int x = 0; x < 64; ++x) expected.at<std::uint8_t>(y, x) = static_cast<std::uint8_t>((x * 3 + y * 5 + n * 7) % 256);
      EXPECT_EQ(cv::norm(f.image, expected, cv::NORM_INF), 0.0) << n;
      EXPECT_EQ(f.gray.data, f.image.data) << "GREY needs no conversion";
    }
    EXPECT_TRUE(camera->violations.empty()) << Joined(camera->violations);
    ASSERT_EQ(camera->dequeued.size(), 20u);
    for (size_t i = 0; i < 20; ++i) EXPECT_EQ(camera->dequeued[i], i % 4) << "4 buffers in turn";
  }
  EXPECT_EQ(camera->mapped, 0) << "every buffer unmapped";
  EXPECT_EQ(camera->stream_offs, 1);
  EXPECT_EQ(camera->closes, camera->opens);
}

TEST(V4l2FrameSource, WaitsThroughEagainWakeups) {
  auto camera = GreyCamera(0);
  camera->script = {FakeStep{}, {FakeStep::kEagain}, {FakeStep::kEagain}, {FakeStep::kEagain}, FakeStep{}};
  auto source = Open(camera, Settings());
  ASSERT_TRUE(source);
  for (int n = 0; n < 2; ++n) {
    auto frame = (*source)->Next();
    ASSERT_TRUE(frame && frame->has_value()) << (frame ? "" : frame.error().message);
    EXPECT_EQ((*frame)->index, static_cast<FrameId>(n));
  }
}

TEST(V4l2FrameSource, ATimeoutIsAOneLineErrorNamingTheDeviceAndTheLastFrame) {
  auto camera = GreyCamera(3);
  camera->script.push_back({FakeStep::kTimeout});
  auto source = Open(camera, Settings());
  ASSERT_TRUE(source);
  for (int n = 0; n < 3; ++n) ASSERT_TRUE((*source)->Next());
  auto lost = (*source)->Next();
  ASSERT_FALSE(lost);
  const std::string& message = lost.error().message;
  EXPECT_TRUE(Contains(message, "v4l2:/dev/video7")) << message;
  EXPECT_TRUE(Contains(message, "after frame 2")) << message;
  EXPECT_TRUE(Contains(message, "no frame for 2.0 s")) << message;
  EXPECT_FALSE(Contains(message, "\n"));
  EXPECT_FALSE((*source)->Next()) << "a lost camera keeps failing";
  EXPECT_EQ(camera->mapped, 0);
}

class LostMidStream : public ::testing::TestWithParam<int> {};

TEST_P(LostMidStream, KeepsEveryFrameRecordedBeforeIt) {
  testing::TempDir tmp;
  auto camera = GreyCamera(5);
  camera->script.push_back({FakeStep::kError, GetParam()});
  camera->gone_for_good = true;
  auto source = Open(camera, Settings());
  ASSERT_TRUE(source);
  RecordingInfo info;
  info.targets.size_m = 0.05;
  auto writer = RecordingWriter::Create(tmp.path() / "rec", info);
  ASSERT_TRUE(writer);
  std::atomic<bool> stop{false};
  const RecordSummary summary = RecordFrames(**source, **writer, stop);
  EXPECT_EQ(summary.frames_written, 5u);
  ASSERT_TRUE(summary.error);
  const std::string& message = summary.error->message;
  EXPECT_TRUE(Contains(message, "v4l2:/dev/video7: camera lost after frame 4")) << message;
  EXPECT_TRUE(Contains(message, std::strerror(GetParam()))) << message;
  EXPECT_FALSE(Contains(message, "\n"));
  auto reader = RecordingReader::Open(tmp.path() / "rec");
  ASSERT_TRUE(reader);
  ASSERT_EQ(reader->entries().size(), 5u);
  for (size_t i = 0; i < 5; ++i) {
    auto frame = reader->LoadFrame(i);
    ASSERT_TRUE(frame);
    EXPECT_EQ(frame->image.at<std::uint8_t>(10, 20), (20 * 3 + 10 * 5 + static_cast<int>(i) * 7) % 256);
  }
}

INSTANTIATE_TEST_SUITE_P(V4l2FrameSource, LostMidStream, ::testing::Values(ENODEV, EIO));

TEST(V4l2FrameSource, WaitsForACameraThatComesBackWhenConfigured) {
  auto camera = GreyCamera(3);
  camera->script.push_back({FakeStep::kError, ENODEV});
  for (int i = 0; i < 3; ++i) camera->script.push_back(FakeStep{});
  camera->opens_to_fail = 2;
  CaptureSettings settings = Settings();
  settings.reconnect_wait_s = 5.0;
  settings.gain = 10;  // the camera has no gain: warned once, not again after the reconnect
  auto source = Open(camera, settings);
  ASSERT_TRUE(source);
  for (int n = 0; n < 6; ++n) {
    auto frame = (*source)->Next();
    ASSERT_TRUE(frame && frame->has_value()) << n << ": " << (frame ? "" : frame.error().message);
    EXPECT_EQ((*frame)->index, static_cast<FrameId>(n));
  }
  EXPECT_EQ(camera->opens, 2);
  EXPECT_EQ(camera->stream_ons, 2);
  const std::string warnings = Joined((*source)->TakeWarnings());
  EXPECT_TRUE(Contains(warnings, "camera lost after frame 2 (No such device); it came back after")) << warnings;
  const size_t first = warnings.find("has no gain control");
  EXPECT_NE(first, std::string::npos) << warnings;
  EXPECT_EQ(warnings.find("has no gain control", first + 1), std::string::npos) << warnings;
  EXPECT_TRUE(camera->violations.empty()) << Joined(camera->violations);
}

TEST(V4l2FrameSource, GivesUpOnACameraThatDoesNotComeBackInTime) {
  auto camera = GreyCamera(2);
  camera->script.push_back({FakeStep::kError, ENODEV});
  camera->gone_for_good = true;
  CaptureSettings settings = Settings();
  settings.reconnect_wait_s = 0.5;
  auto source = Open(camera, settings);
  ASSERT_TRUE(source);
  ASSERT_TRUE((*source)->Next());
  ASSERT_TRUE((*source)->Next());
  auto lost = (*source)->Next();
  ASSERT_FALSE(lost);
  EXPECT_TRUE(Contains(lost.error().message, "camera lost after frame 1 (No such device); it did not come back within 0.5 s"))
      << lost.error().message;
}

TEST(V4l2FrameSource, AFormatTheCameraRefusesIsAnErrorSayingWhy) {
  auto camera = GreyCamera(1);
  camera->s_fmt_error = EBUSY;
  auto refused = Open(camera, Settings());
  ASSERT_FALSE(refused);
  EXPECT_EQ(refused.error().message, "v4l2:/dev/video7: refuses the format GREY 64x48 (Device or resource busy)");
  EXPECT_EQ(camera->closes, camera->opens);

  camera = GreyCamera(1);
  camera->formats = {V4L2_PIX_FMT_YUYV, V4L2_PIX_FMT_GREY};
  CaptureSettings settings = Settings();
  settings.pixel_format = "MJPG";
  auto absent = Open(camera, settings);
  ASSERT_FALSE(absent);
  EXPECT_EQ(absent.error().message, "v4l2:/dev/video7: does not offer pixel format MJPG (it offers YUYV, GREY)");

  camera->formats = {V4L2_PIX_FMT_NV12};
  auto undecodable = Open(camera, Settings());
  ASSERT_FALSE(undecodable);
  EXPECT_TRUE(Contains(undecodable.error().message, "offers no pixel format tagsfm decodes (it offers NV12"))
      << undecodable.error().message;
}

TEST(V4l2FrameSource, TakesTheYPlaneOfYuyvAsTheGreyImage) {
  auto camera = std::make_shared<FakeCamera>();
  camera->formats = {V4L2_PIX_FMT_MJPEG, V4L2_PIX_FMT_YUYV};
  camera->script.assign(2, FakeStep{});
  camera->frame_bytes = [](int n) {
    std::vector<std::uint8_t> bytes;
    for (int y = 0; y < 48; ++y)
      for (int x = 0; x < 64; ++x) {
        bytes.push_back(static_cast<std::uint8_t>(x + y + n));  // Y
        bytes.push_back(static_cast<std::uint8_t>(x % 2 ? 200 : 60));  // U or V
      }
    return bytes;
  };
  auto source = Open(camera, Settings());
  ASSERT_TRUE(source) << source.error().message;
  EXPECT_EQ(camera->pixel_format, static_cast<std::uint32_t>(V4L2_PIX_FMT_YUYV)) << "grey prefers YUYV's luma to JPEG";
  auto frame = (*source)->Next();
  ASSERT_TRUE(frame && frame->has_value());
  const Frame& f = **frame;
  ASSERT_EQ(f.gray.type(), CV_8UC1);
  EXPECT_EQ(f.gray.at<std::uint8_t>(7, 11), 18);
  EXPECT_EQ(f.gray.at<std::uint8_t>(47, 63), 110);
  EXPECT_EQ(f.image.data, f.gray.data) << "grey frames record the Y plane itself";
}

TEST(V4l2FrameSource, DecodesMjpegAndSkipsCorruptFrames) {
  auto camera = std::make_shared<FakeCamera>();
  camera->formats = {V4L2_PIX_FMT_MJPEG};
  cv::Mat picture(48, 64, CV_8UC1);
  for (int y = 0; y < 48; ++y)
    for (int x = 0; x < 64; ++x) picture.at<std::uint8_t>(y, x) = static_cast<std::uint8_t>(40 + 2 * x + y);
  std::vector<std::uint8_t> jpeg;
  cv::imencode(".jpg", picture, jpeg, {cv::IMWRITE_JPEG_QUALITY, 95});
  camera->frame_bytes = [jpeg](int n) { return n == 1 ? std::vector<std::uint8_t>(200, 0x55) : jpeg; };
  camera->script = {FakeStep{}, FakeStep{}, {FakeStep::kCorrupt}, FakeStep{}};
  auto source = Open(camera, Settings());
  ASSERT_TRUE(source) << source.error().message;
  for (int n = 0; n < 2; ++n) {
    auto frame = (*source)->Next();
    ASSERT_TRUE(frame && frame->has_value());
    EXPECT_EQ((*frame)->index, static_cast<FrameId>(n)) << "corrupt frames take no index";
    EXPECT_LT(cv::norm((*frame)->gray, picture, cv::NORM_L1) / picture.total(), 2.0) << "JPEG q95 of a smooth ramp";
  }
  const std::string warnings = Joined((*source)->TakeWarnings());
  EXPECT_TRUE(Contains(warnings, "2 corrupt frames skipped")) << warnings;
  EXPECT_TRUE(camera->violations.empty()) << Joined(camera->violations);
  EXPECT_EQ(camera->dequeued.size(), 4u);
}

TEST(V4l2FrameSource, AppliesControlsAndWarnsOnceAboutEachItCannot) {
  auto camera = GreyCamera(1);
  camera->controls[V4L2_CID_EXPOSURE_AUTO] = {0, 3, V4L2_EXPOSURE_AUTO};
  camera->controls[V4L2_CID_EXPOSURE_ABSOLUTE] = {1, 5000, 300};
  camera->controls[V4L2_CID_GAIN] = {0, 100, 30};
  camera->controls[V4L2_CID_BRIGHTNESS] = {-64, 64, 0};
  CaptureSettings settings = Settings();
  settings.exposure_us = 4000;
  settings.gain = 500;
  settings.brightness = -20;
  auto source = Open(camera, settings);
  ASSERT_TRUE(source);
  EXPECT_EQ(camera->controls[V4L2_CID_EXPOSURE_AUTO].value, V4L2_EXPOSURE_MANUAL);
  EXPECT_EQ(camera->controls[V4L2_CID_EXPOSURE_ABSOLUTE].value, 40) << "100 µs units";
  EXPECT_EQ(camera->controls[V4L2_CID_BRIGHTNESS].value, -20);
  EXPECT_EQ(camera->controls[V4L2_CID_GAIN].value, 30) << "out of range: left as it was";
  const std::vector<std::string> warnings = (*source)->TakeWarnings();
  ASSERT_EQ(warnings.size(), 2u) << Joined(warnings);
  EXPECT_EQ(warnings[0], "v4l2:/dev/video7: has no autofocus control (fixed focus?): capture.autofocus: false has nothing to switch off");
  EXPECT_EQ(warnings[1], "v4l2:/dev/video7: capture.gain asks gain 500, outside the camera's range 0..100: left unchanged");
  EXPECT_TRUE((*source)->TakeWarnings().empty()) << "said once";
}

TEST(V4l2FrameSource, SaysWhenTheCameraKeepsADifferentValueOrRefuses) {
  auto camera = GreyCamera(1);
  camera->controls[V4L2_CID_FOCUS_AUTO] = {0, 1, 1};
  camera->controls[V4L2_CID_FOCUS_AUTO].set_error = EACCES;
  camera->controls[V4L2_CID_GAIN] = {0, 100, 30};
  camera->controls[V4L2_CID_GAIN].keeps = 32;
  CaptureSettings settings = Settings();
  settings.gain = 33;
  auto source = Open(camera, settings);
  ASSERT_TRUE(source);
  const std::string warnings = Joined((*source)->TakeWarnings());
  EXPECT_TRUE(Contains(warnings, "cannot set autofocus to 0 for capture.autofocus (Permission denied)")) << warnings;
  EXPECT_TRUE(Contains(warnings, "capture.gain asked gain 33, the camera kept 32")) << warnings;
}

TEST(V4l2FrameSource, CountsFramesTheDriverDropped) {
  auto camera = GreyCamera(0);
  camera->script = {FakeStep{}, FakeStep{}, {FakeStep::kFrame, 0, 3}, FakeStep{}};
  auto source = Open(camera, Settings());
  ASSERT_TRUE(source);
  for (int n = 0; n < 4; ++n) ASSERT_TRUE((*source)->Next());
  const std::string warnings = Joined((*source)->TakeWarnings());
  EXPECT_TRUE(Contains(warnings, "the driver dropped 3 frames so far")) << warnings;
}

}  // namespace
}  // namespace tagsfm
