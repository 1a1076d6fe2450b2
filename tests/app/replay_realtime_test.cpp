// `tagsfm replay --realtime`: paced at the recording's timestamps, with the
// live dashboard served, and the same results as a plain replay (targets
// only: the features are the same code either way, tested elsewhere).
#include <chrono>
#include <cstdlib>
#include <fstream>
#include <sstream>

#include <gtest/gtest.h>

#include "tagsfm/capture/recording.h"
#include "run_command.h"
#include "tagsfm/core/csv_formats.h"
#include "test_paths.h"

namespace tagsfm {
namespace {

using testing::ReadText;
using testing::RunCommand;
using testing::TempDir;

TEST(ReplayRealtime, TakesAtLeastTheRecordingsDurationAndGivesThePlainReplaysResult) {
  const auto recording = testing::RecordingsDir() / "box_small";
  if (!std::filesystem::exists(recording)) GTEST_SKIP() << "recordings/box_small is missing";
  auto reader = RecordingReader::Open(recording);
  ASSERT_TRUE(reader) << reader.error().message;
  const auto& entries = reader->entries();
  ASSERT_GE(entries.size(), 2u);
  const double duration_s = (entries.back().timestamp_ns - entries.front().timestamp_ns) * 1e-9;

  TempDir tmp;
  const std::string exe = testing::TagsfmExe().string();
  const auto start = std::chrono::steady_clock::now();
  ASSERT_EQ(RunCommand(exe + " replay " + recording.string() + " --out " + (tmp.path() / "paced").string() +
                           " --realtime --dashboard 127.0.0.1:0 --no-features",
                       tmp.path() / "paced.log"),
            0)
      << ReadText(tmp.path() / "paced.log");
  const double wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  // Paced: the last frame is not processed before its time (a lower bound
  // only, which a slow machine cannot break).
  EXPECT_GE(wall_s, duration_s) << "replayed " << duration_s << " s of frames in " << wall_s << " s";
  EXPECT_NE(ReadText(tmp.path() / "paced.log").find("dashboard at http://127.0.0.1:"), std::string::npos)
      << ReadText(tmp.path() / "paced.log");

  ASSERT_EQ(RunCommand(exe + " replay " + recording.string() + " --out " + (tmp.path() / "plain").string() + " --no-features",
                       tmp.path() / "plain.log"),
            0)
      << ReadText(tmp.path() / "plain.log");
  auto paced = ReadPosesCsv(tmp.path() / "paced" / "poses.csv");
  auto plain = ReadPosesCsv(tmp.path() / "plain" / "poses.csv");
  ASSERT_TRUE(paced && plain);
  ASSERT_EQ(paced->size(), plain->size());
  ASSERT_GT(plain->size(), entries.size() / 2);
  for (const auto& [frame, pose] : *plain) {
    ASSERT_TRUE(paced->count(frame)) << "frame " << frame;
    // Same frames through the same code: equal to round-off (multi-threaded
    // reductions may differ in the last bits).
    EXPECT_LT((pose.translation - paced->at(frame).translation).norm(), 1e-9) << "frame " << frame;
    EXPECT_LT(RotationAngleDeg(pose.rotation, paced->at(frame).rotation), 1e-7) << "frame " << frame;
  }
}

}  // namespace
}  // namespace tagsfm
