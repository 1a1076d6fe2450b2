// replay, replay --realtime and run (a recording played as the camera) drive
// the one pipeline: the same frames give the same poses, targets and points,
// features included.
#include <algorithm>
#include <cmath>
#include <fstream>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "json_file.h"
#include "run_command.h"
#include "tagsfm/core/csv_formats.h"
#include "tagsfm/eval/ply_reader.h"
#include "test_paths.h"

namespace tagsfm {
namespace {

namespace fs = std::filesystem;
using testing::ReadJsonFile;
using testing::ReadText;
using testing::RunCommand;
using testing::TempDir;

// Same frames through the same code: the same numbers, bit for bit (the
// bounds only keep the messages readable). Two sources of run-to-run
// noise were removed for this: the sliding window's fast removal (a hash
// set of pointers) and Ceres' threaded Schur elimination in the global
// adjustment (global_threads 1); the features' refinement amplified their
// 1e-17 m into 1e-6 m and a few points more or less.
constexpr double kSameM = 1e-12;
constexpr double kSameDeg = 1e-10;

void ExpectSameResults(const fs::path& a, const fs::path& b) {
  auto poses_a = ReadPosesCsv(a / "poses.csv");
  auto poses_b = ReadPosesCsv(b / "poses.csv");
  ASSERT_TRUE(poses_a && poses_b);
  ASSERT_GE(poses_a->size(), 8u);  // the smallest bundled recording has 8 frames
  ASSERT_EQ(poses_a->size(), poses_b->size());
  for (const auto& [frame, pose] : *poses_a) {
    ASSERT_TRUE(poses_b->count(frame)) << "frame " << frame;
    EXPECT_LT((pose.translation - poses_b->at(frame).translation).norm(), kSameM) << "frame " << frame;
    EXPECT_LT(RotationAngleDeg(pose.rotation, poses_b->at(frame).rotation), kSameDeg) << "frame " << frame;
  }
  auto targets_a = ReadTargetsCsv(a / "targets.csv");
  auto targets_b = ReadTargetsCsv(b / "targets.csv");
  ASSERT_TRUE(targets_a && targets_b);
  ASSERT_EQ(targets_a->size(), targets_b->size());
  for (const auto& [id, corners] : *targets_a) {
    ASSERT_TRUE(targets_b->count(id)) << "tag " << id;
    for (size_t k = 0; k < 4; ++k) EXPECT_LT((corners[k] - targets_b->at(id)[k]).norm(), kSameM) << "tag " << id;
  }
  // cloud.ply: the targets' corners, then the feature points, in one order.
  auto cloud_a = eval::ReadPlyPoints(a / "cloud.ply");
  auto cloud_b = eval::ReadPlyPoints(b / "cloud.ply");
  ASSERT_TRUE(cloud_a && cloud_b);
  ASSERT_GT(cloud_a->size(), 4 * targets_a->size() + 100) << "too few feature points to compare";
  const double count_a = static_cast<double>(cloud_a->size()), count_b = static_cast<double>(cloud_b->size());
  EXPECT_EQ(count_a, count_b) << "points";
  double worst = 0;
  for (size_t i = 0; i < std::min(cloud_a->size(), cloud_b->size()); ++i) {
    worst = std::max(worst, ((*cloud_a)[i] - (*cloud_b)[i]).norm());
  }
  EXPECT_LT(worst, kSameM) << "largest difference between the two clouds' points, m";
}

// Each bundled recording: a video round a box, a video of a wall, photos
// two seconds apart.
class PipelinePaths : public ::testing::TestWithParam<std::string> {
 protected:
  void SetUp() override {
    if (!fs::exists(source_)) GTEST_SKIP() << source_ << " is missing";
  }
  int Tagsfm(const std::string& args, const std::string& log) {
    return RunCommand(testing::TagsfmExe().string() + " " + args, tmp_.path() / log);
  }
  fs::path Replay(const std::string& name, const std::string& extra) {
    const fs::path out = tmp_.path() / name;
    EXPECT_EQ(Tagsfm("replay " + source_.string() + " --out " + out.string() + " " + extra, name + ".log"), 0)
        << ReadText(tmp_.path() / (name + ".log"));
    return out;
  }
  const fs::path source_ = testing::RecordingsDir() / GetParam();
  TempDir tmp_;
};

TEST_P(PipelinePaths, ReplayAndRealtimeReplayGiveTheSameResult) {
  ExpectSameResults(Replay("plain", ""), Replay("paced", "--realtime --dashboard 127.0.0.1:0"));
}

TEST_P(PipelinePaths, RunOnTheRecordingGivesTheReplaysResult) {
  const fs::path config = tmp_.path() / "run.yaml";
  std::ofstream(config) << "capture:\n  source: file:" << source_.string() << "?rate=max\n"
                        << "run:\n  record_dir: " << (tmp_.path() / "live").string() << "\n  dashboard: 127.0.0.1:0\n"
                        << "  max_queue_frames: 1000\n";  // no live drops: every frame reaches the pipeline
  ASSERT_EQ(Tagsfm("run --config " + config.string(), "run.log"), 0) << ReadText(tmp_.path() / "run.log");
  ExpectSameResults(Replay("plain", ""), tmp_.path() / "live" / "results");
}

std::string RecordingName(const ::testing::TestParamInfo<std::string>& info) { return info.param; }

INSTANTIATE_TEST_SUITE_P(BundledRecordings, PipelinePaths, ::testing::Values("box_small", "wall_small", "box_photos"),
                         RecordingName);

using PipelineConfig = PipelinePaths;

TEST_P(PipelineConfig, ReplayConfigSetsThePipelinesOptionsAndNamesAWrongField) {
  const fs::path config = tmp_.path() / "replay.yaml";
  std::ofstream(config) << "pipeline:\n  features:\n    enabled: false\n  tag_search: every_frame\n";
  const fs::path out = Replay("configured", "--config " + config.string());
  const auto report = ReadJsonFile(out / "report.json");
  EXPECT_EQ(report["feature_points"].get<int>(), 0);
  EXPECT_EQ(report["tag_search"]["mode"], "every_frame");
  EXPECT_EQ(report["tag_search"]["full_frame_detections"].get<int>(), report["frames"].get<int>());

  std::ofstream(config) << "pipeline:\n  recon:\n    ba:\n      huber_px: -1\n";
  EXPECT_NE(Tagsfm("replay " + source_.string() + " --out " + (tmp_.path() / "bad").string() + " --config " +
                       config.string(),
                   "bad.log"),
            0);
  const std::string log = ReadText(tmp_.path() / "bad.log");
  EXPECT_NE(log.find(config.string() + ": pipeline.recon.ba.huber_px must be > 0"), std::string::npos) << log;
  EXPECT_EQ(std::count(log.begin(), log.end(), '\n'), 1) << log;
}

INSTANTIATE_TEST_SUITE_P(BoxSmall, PipelineConfig, ::testing::Values("box_small"), RecordingName);

}  // namespace
}  // namespace tagsfm
