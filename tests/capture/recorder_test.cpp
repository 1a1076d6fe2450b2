#include "tagsfm/capture/recorder.h"

#include <gtest/gtest.h>

#include "recording_test_util.h"
#include "tagsfm/capture/capture_settings.h"
#include "test_paths.h"

namespace tagsfm {
namespace {

using testing::TempDir;

// A camera that delivers `frames_before_vanishing` frames, then fails the way
// an unplugged USB camera does.
class VanishingCamera : public FrameSource {
 public:
  explicit VanishingCamera(int frames_before_vanishing) : remaining_(frames_before_vanishing) {
    info_.targets.size_m = 0.05;
  }
  Result<std::optional<Frame>> Next() override {
    if (remaining_-- <= 0) return MakeError("v4l2:/dev/video9: camera stopped delivering frames");
    Frame frame;
    frame.index = next_++;
    frame.timestamp_ns = frame.index * 1000;
    frame.image = testing::TestImage(static_cast<int>(frame.index));
    return std::optional<Frame>(std::move(frame));
  }
  const RecordingInfo& info() const override { return info_; }
  std::string uri() const override { return "v4l2:/dev/video9"; }

 private:
  RecordingInfo info_;
  int remaining_;
  FrameId next_ = 0;
};

TEST(Recorder, ACameraThatVanishesLosesNoFrameAlreadyRecorded) {
  TempDir tmp;
  VanishingCamera camera(5);
  auto writer = RecordingWriter::Create(tmp.path() / "rec", camera.info());
  ASSERT_TRUE(writer);
  std::atomic<bool> stop{false};
  int seen = 0;
  const RecordSummary summary = RecordFrames(camera, **writer, stop, 0, [&](const Frame&) { ++seen; });
  ASSERT_TRUE(summary.error.has_value());
  EXPECT_NE(summary.error->message.find("/dev/video9"), std::string::npos);
  EXPECT_EQ(summary.frames_written, 5u);
  EXPECT_EQ(seen, 5);
  auto reader = RecordingReader::Open(tmp.path() / "rec");
  ASSERT_TRUE(reader);
  ASSERT_EQ(reader->entries().size(), 5u);
  for (size_t i = 0; i < 5; ++i) EXPECT_TRUE(reader->LoadFrame(i));
}

TEST(Recorder, StopsAtTheFrameLimitOrWhenAsked) {
  TempDir tmp;
  VanishingCamera camera(100);
  auto writer = RecordingWriter::Create(tmp.path() / "rec", camera.info());
  ASSERT_TRUE(writer);
  std::atomic<bool> stop{false};
  EXPECT_EQ(RecordFrames(camera, **writer, stop, 3).frames_written, 3u);
  stop = true;
  EXPECT_EQ(RecordFrames(camera, **writer, stop).frames_written, 0u);
}

TEST(CaptureSettings, ReadsTheCaptureBlockAndNamesBadFields) {
  TempDir tmp;
  const auto path = tmp.path() / "cam.yaml";
  testing::WriteTextFile(path, "capture:\n  source: v4l2:/dev/video2\n  width: 1920\n  height: 1080\n  fps: 15\n"
                               "  exposure_us: 4000\n  autofocus: false\n");
  auto settings = ReadCaptureSettings(path);
  ASSERT_TRUE(settings) << settings.error().message;
  EXPECT_EQ(settings->source, "v4l2:/dev/video2");
  EXPECT_EQ(settings->width, 1920);
  EXPECT_EQ(settings->exposure_us, 4000);
  EXPECT_TRUE(settings->Warnings().empty());

  testing::WriteTextFile(path, "capture:\n  fps: fast\n");
  settings = ReadCaptureSettings(path);
  ASSERT_FALSE(settings);
  EXPECT_NE(settings.error().message.find("capture.fps"), std::string::npos) << settings.error().message;

  testing::WriteTextFile(path, "capture:\n  buffers: 1\n");
  settings = ReadCaptureSettings(path);
  ASSERT_FALSE(settings);
  EXPECT_NE(settings.error().message.find("capture.buffers"), std::string::npos) << settings.error().message;

  CaptureSettings risky;
  risky.autofocus = true;
  EXPECT_EQ(risky.Warnings().size(), 2u);  // autofocus on, automatic exposure
}

TEST(FrameSource, AMissingCameraIsAClearError) {
  auto source = OpenFrameSource("v4l2:/dev/video_that_does_not_exist");
  ASSERT_FALSE(source);
  EXPECT_NE(source.error().message.find("/dev/video_that_does_not_exist"), std::string::npos);
}

}  // namespace
}  // namespace tagsfm
