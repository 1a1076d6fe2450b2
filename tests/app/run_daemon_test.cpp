// The live daemon end to end, with a recording played as its camera.
#include <algorithm>
#include <cstdlib>
#include <fstream>
#include <sstream>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "tagsfm/capture/recording.h"
#include "run_command.h"
#include "tagsfm/core/csv_formats.h"
#include "test_paths.h"

namespace tagsfm {
namespace {

using testing::ReadText;
using testing::RunCommand;
using testing::TempDir;

TEST(RunDaemon, RecordsEveryFrameAndGivesTheSameResultAsAReplay) {
  const auto source = testing::RecordingsDir() / "box_small";
  if (!std::filesystem::exists(source)) GTEST_SKIP() << "recordings/box_small is missing";
  TempDir tmp;
  const auto config = tmp.path() / "run.yaml";
  std::ofstream(config) << "capture:\n  source: file:" << source.string() << "\n  exposure_us: 1000\n"
                        << "run:\n  record_dir: " << (tmp.path() / "live").string() << "\n  dashboard: 127.0.0.1:0\n";
  ASSERT_EQ(RunCommand(testing::TagsfmExe().string() + " run --config " + config.string(), tmp.path() / "run.log"), 0)
      << ReadText(tmp.path() / "run.log");

  // Every frame recorded, pixel for pixel.
  auto original = RecordingReader::Open(source);
  auto recorded = RecordingReader::Open(tmp.path() / "live");
  ASSERT_TRUE(original && recorded);
  ASSERT_EQ(recorded->entries().size(), original->entries().size());
  for (size_t i = 0; i < original->entries().size(); ++i) {
    auto a = original->LoadFrame(i);
    auto b = recorded->LoadFrame(i);
    ASSERT_TRUE(a && b);
    EXPECT_EQ(b->timestamp_ns, a->timestamp_ns);
    EXPECT_EQ(cv::norm(a->image, b->image, cv::NORM_INF), 0) << "frame " << i;
  }

  // Offline replay of what the daemon recorded gives the daemon's result.
  const auto replay_out = tmp.path() / "replay";
  ASSERT_EQ(RunCommand(testing::TagsfmExe().string() + " replay " + (tmp.path() / "live").string() + " --out " +
                    replay_out.string(),
                tmp.path() / "replay.log"),
            0)
      << ReadText(tmp.path() / "replay.log");
  auto live_poses = ReadPosesCsv(tmp.path() / "live" / "results" / "poses.csv");
  auto replay_poses = ReadPosesCsv(replay_out / "poses.csv");
  ASSERT_TRUE(live_poses && replay_poses);
  ASSERT_GT(live_poses->size(), original->entries().size() / 2);
  ASSERT_EQ(live_poses->size(), replay_poses->size());
  for (const auto& [frame, pose] : *live_poses) {
    ASSERT_TRUE(replay_poses->count(frame));
    // Same frames through the same code: equal to round-off.
    EXPECT_LT((pose.translation - replay_poses->at(frame).translation).norm(), 1e-9) << "frame " << frame;
    EXPECT_LT(RotationAngleDeg(pose.rotation, replay_poses->at(frame).rotation), 1e-7) << "frame " << frame;
  }
  // Feature points: the daemon selects the same keyframes live and tracks
  // them from the recording at the end, so it finds the replay's points.
  const auto live_report = nlohmann::json::parse(ReadText(tmp.path() / "live" / "results" / "report.json"));
  const auto replay_report = nlohmann::json::parse(ReadText(replay_out / "report.json"));
  EXPECT_GT(live_report["feature_points"].get<int>(), 0);
  EXPECT_EQ(live_report["feature_points"].get<int>(), replay_report["feature_points"].get<int>());
  EXPECT_EQ(live_report["feature_keyframes"].get<int>(), replay_report["feature_keyframes"].get<int>());
  // Both found the tags by tracking (the default), with the map's predictions.
  EXPECT_EQ(live_report["tag_search"]["mode"], "tracking");
  EXPECT_EQ(live_report["tag_search"], replay_report["tag_search"]);
}

TEST(RunDaemon, ABadConfigIsAOneLineErrorNamingTheField) {
  TempDir tmp;
  const auto config = tmp.path() / "run.yaml";
  std::ofstream(config) << "capture:\n  source: v4l2:/dev/video0\n  fps: -5\nrun:\n  record_dir: x\n";
  EXPECT_NE(RunCommand(testing::TagsfmExe().string() + " run --config " + config.string(), tmp.path() / "log"), 0);
  const std::string log = ReadText(tmp.path() / "log");
  EXPECT_NE(log.find("capture.fps"), std::string::npos) << log;
  EXPECT_EQ(std::count(log.begin(), log.end(), '\n'), 1) << log;

  std::ofstream(config) << "capture:\n  source: v4l2:/dev/video_missing\n";
  EXPECT_NE(RunCommand(testing::TagsfmExe().string() + " run --config " + config.string(), tmp.path() / "log"), 0);
  EXPECT_NE(ReadText(tmp.path() / "log").find("run.record_dir"), std::string::npos) << ReadText(tmp.path() / "log");

  std::ofstream(config) << "capture:\n  source: v4l2:/dev/video_missing\nrun:\n  record_dir: "
                        << (tmp.path() / "rec").string() << "\n";
  EXPECT_NE(RunCommand(testing::TagsfmExe().string() + " run --config " + config.string(), tmp.path() / "log"), 0);
  EXPECT_NE(ReadText(tmp.path() / "log").find("/dev/video_missing"), std::string::npos) << ReadText(tmp.path() / "log");

  std::ofstream(config) << "capture:\n  source: v4l2:/dev/video_missing\nrun:\n  record_dir: "
                        << (tmp.path() / "rec").string() << "\n  tag_search: sometimes\n";
  EXPECT_NE(RunCommand(testing::TagsfmExe().string() + " run --config " + config.string(), tmp.path() / "log"), 0);
  EXPECT_NE(ReadText(tmp.path() / "log").find("run.tag_search"), std::string::npos) << ReadText(tmp.path() / "log");
}

}  // namespace
}  // namespace tagsfm
