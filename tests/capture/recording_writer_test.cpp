#include "tagsfm/capture/recording_writer.h"

#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <thread>

#include <gtest/gtest.h>

#include "recording_test_util.h"
#include "tagsfm/capture/frame_source.h"
#include "test_paths.h"

namespace tagsfm {
namespace {

using testing::TempDir;
using testing::TestImage;

RecordingInfo SmallInfo() {
  RecordingInfo info;
  CameraModel camera;
  camera.width = 64;
  camera.height = 48;
  camera.fx = camera.fy = 50;
  camera.cx = 32;
  camera.cy = 24;
  info.camera = camera;
  info.targets.size_m = 0.05;
  return info;
}

Frame MakeFrame(FrameId index, int type = CV_8UC1) {
  Frame frame;
  frame.index = index;
  frame.timestamp_ns = index * 33'333'333;
  frame.image = TestImage(static_cast<int>(index), type);
  return frame;
}

TEST(RecordingWriter, WrittenFramesReadBackLosslessly) {
  TempDir tmp;
  const auto rec = tmp.path() / "rec";
  auto writer = RecordingWriter::Create(rec, SmallInfo());
  ASSERT_TRUE(writer) << writer.error().message;
  const int types[] = {CV_8UC1, CV_16UC1, CV_8UC3, CV_16UC3};
  for (int i = 0; i < 8; ++i) ASSERT_TRUE((*writer)->Append(MakeFrame(i, types[i % 4])));
  EXPECT_EQ((*writer)->frames_written(), 8u);

  auto reader = RecordingReader::Open(rec);
  ASSERT_TRUE(reader) << reader.error().message;
  ASSERT_EQ(reader->entries().size(), 8u);
  EXPECT_EQ(reader->info().camera->fx, 50);
  for (int i = 0; i < 8; ++i) {
    auto frame = reader->LoadFrame(i);
    ASSERT_TRUE(frame) << frame.error().message;
    EXPECT_EQ(frame->timestamp_ns, i * 33'333'333);
    EXPECT_EQ(frame->image.type(), types[i % 4]);
    EXPECT_EQ(cv::norm(frame->image, TestImage(i, types[i % 4]), cv::NORM_INF), 0) << "frame " << i;
  }
}

TEST(RecordingWriter, RefusesToOverwriteARecordingOrWriteABadConfig) {
  TempDir tmp;
  ASSERT_TRUE(RecordingWriter::Create(tmp.path() / "rec", SmallInfo()));
  auto again = RecordingWriter::Create(tmp.path() / "rec", SmallInfo());
  ASSERT_FALSE(again);
  EXPECT_NE(again.error().message.find("not empty"), std::string::npos) << again.error().message;

  RecordingInfo bad = SmallInfo();
  bad.targets.family = "tag12h34";
  auto wrong = RecordingWriter::Create(tmp.path() / "rec2", bad);
  ASSERT_FALSE(wrong);
  EXPECT_NE(wrong.error().message.find("tag12h34"), std::string::npos);
}

// A recorder killed with SIGKILL at an arbitrary moment must leave a
// recording whose every listed frame reads back, including every frame it
// had reported as written before the kill.
TEST(RecordingWriter, SurvivesSigkillWithEveryWrittenFrame) {
  TempDir tmp;
  const auto rec = tmp.path() / "rec";
  int pipe_fds[2];
  ASSERT_EQ(::pipe(pipe_fds), 0);
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    ::close(pipe_fds[0]);
    auto writer = RecordingWriter::Create(rec, SmallInfo());
    if (!writer) ::_exit(2);
    for (int i = 0; i < 100000; ++i) {
      if (!(*writer)->Append(MakeFrame(i))) ::_exit(3);
      const int done = i + 1;
      if (::write(pipe_fds[1], &done, sizeof done) != sizeof done) ::_exit(4);
    }
    ::_exit(0);
  }
  ::close(pipe_fds[1]);
  int reported = 0, value = 0;
  // Let the child write a few frames, then kill it mid-stream.
  while (reported < 20 && ::read(pipe_fds[0], &value, sizeof value) == sizeof value) reported = value;
  ASSERT_EQ(::kill(child, SIGKILL), 0);
  int status = 0;
  ::waitpid(child, &status, 0);
  while (::read(pipe_fds[0], &value, sizeof value) == sizeof value) reported = value;
  ::close(pipe_fds[0]);
  ASSERT_TRUE(WIFSIGNALED(status)) << "the writer should have been killed, not exited";

  auto reader = RecordingReader::Open(rec);
  ASSERT_TRUE(reader) << reader.error().message;
  ASSERT_GE(static_cast<int>(reader->entries().size()), reported);
  for (size_t i = 0; i < reader->entries().size(); ++i) {
    auto frame = reader->LoadFrame(i);
    ASSERT_TRUE(frame) << frame.error().message;
    EXPECT_EQ(cv::norm(frame->image, TestImage(static_cast<int>(i)), cv::NORM_INF), 0);
  }
}

TEST(FileFrameSource, PlaysARecordingAtItsOwnPaceOrAsFastAsPossible) {
  TempDir tmp;
  const auto rec = tmp.path() / "rec";
  {
    auto writer = RecordingWriter::Create(rec, SmallInfo());
    ASSERT_TRUE(writer);
    for (int i = 0; i < 7; ++i) ASSERT_TRUE((*writer)->Append(MakeFrame(i)));  // 6 intervals of 33 ms
  }
  for (const std::string query : {"?rate=max", ""}) {
    auto source = OpenFrameSource("file:" + rec.string() + query);
    ASSERT_TRUE(source) << source.error().message;
    const auto start = std::chrono::steady_clock::now();
    int count = 0;
    while (true) {
      auto frame = (*source)->Next();
      ASSERT_TRUE(frame) << frame.error().message;
      if (!frame->has_value()) break;
      EXPECT_EQ((*frame)->index, count);
      ++count;
    }
    EXPECT_EQ(count, 7);
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    // Paced playback cannot be faster than the recording's 0.2 s span.
    if (query.empty()) {
      EXPECT_GE(seconds, 0.199);
    }
  }
  EXPECT_FALSE(OpenFrameSource("file:" + rec.string() + "?rate=fast"));
  EXPECT_FALSE(OpenFrameSource("gopro:0"));
  EXPECT_FALSE(OpenFrameSource("nocolon"));
}

}  // namespace
}  // namespace tagsfm
