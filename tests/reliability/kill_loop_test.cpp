// Kill loops (a Slow suite: 20 kills of each command): `record`, `run` and
// `replay` killed with SIGKILL at random moments. What was recorded reads
// back pixel for pixel, a replay of it succeeds, and no reader ever sees
// half a result file. The moments are drawn from a fixed seed (printed), so
// a failure can be repeated.
#include <cstdio>
#include <random>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "child_process.h"
#include "run_command.h"
#include "tagsfm/core/csv_formats.h"
#include "tagsfm/eval/ply_reader.h"
#include "test_paths.h"

namespace tagsfm {
namespace {

using testing::ReadText;
using testing::TempDir;
namespace fs = std::filesystem;

constexpr int kKills = 20;
constexpr unsigned kSeed = 16;

// Every frame `recorded` lists is the source's frame of that number, pixel
// for pixel, with its timestamp, and they are the source's first n frames;
// returns n. A recording killed before its frames.csv existed has none.
size_t ExpectPrefixOfSource(const fs::path& recorded, const RecordingReader& source, const std::string& what) {
  if (!fs::exists(recorded / "frames.csv")) return 0;
  auto rec = RecordingReader::Open(recorded);
  EXPECT_TRUE(rec.has_value()) << what << ": " << (rec ? "" : rec.error().message);
  if (!rec) return 0;
  const auto& entries = rec->entries();
  EXPECT_LE(entries.size(), source.entries().size()) << what;
  for (size_t i = 0; i < entries.size() && i < source.entries().size(); ++i) {
    EXPECT_EQ(entries[i].frame, static_cast<FrameId>(i)) << what << ": frames.csv row " << i;
    auto got = rec->LoadFrame(i);
    auto want = source.LoadFrame(i);
    EXPECT_TRUE(got.has_value()) << what << ": " << (got ? "" : got.error().message);
    if (!got || !want) continue;
    EXPECT_EQ(got->timestamp_ns, want->timestamp_ns) << what << ": frame " << i;
    EXPECT_EQ(got->image.type(), want->image.type()) << what << ": frame " << i;
    EXPECT_EQ(got->image.size(), want->image.size()) << what << ": frame " << i;
    if (got->image.type() == want->image.type() && got->image.size() == want->image.size()) {
      EXPECT_EQ(cv::norm(got->image, want->image, cv::NORM_INF), 0) << what << ": frame " << i << " differs";
    }
  }
  return entries.size();
}

// Each result file present is whole: it parses with the reader its format
// has. (The writers put a file in place by rename, so a reader sees all of
// it or none; FILE.tmp may be left half written.) Returns how many were present.
int ExpectWholeResults(const fs::path& dir, const std::string& what) {
  int present = 0;
  if (fs::exists(dir / "report.json")) {
    ++present;
    EXPECT_TRUE(nlohmann::json::accept(ReadText(dir / "report.json"))) << what << ": half a report.json";
  }
  if (fs::exists(dir / "cloud.ply")) {
    ++present;
    auto cloud = eval::ReadPlyPoints(dir / "cloud.ply");
    EXPECT_TRUE(cloud.has_value()) << what << ": " << (cloud ? "" : cloud.error().message);
  }
  if (fs::exists(dir / "targets.csv")) {
    ++present;
    auto targets = ReadTargetsCsv(dir / "targets.csv");
    EXPECT_TRUE(targets.has_value()) << what << ": " << (targets ? "" : targets.error().message);
  }
  if (fs::exists(dir / "poses.csv")) {
    ++present;
    auto poses = ReadPosesCsv(dir / "poses.csv");
    EXPECT_TRUE(poses.has_value()) << what << ": " << (poses ? "" : poses.error().message);
  }
  return present;
}

void ExpectReplaySucceeds(const fs::path& rec, const fs::path& out, const std::string& what) {
  const fs::path log = out.string() + ".log";
  const int code = testing::RunCommand(testing::TagsfmExe().string() + " replay " + rec.string() + " --out " +
                                           out.string() + " --no-features",
                                       log);
  EXPECT_EQ(code, 0) << what << ": replay of the truncated recording failed:\n" << ReadText(log);
}

class KillLoopSlow : public ::testing::Test {
 protected:
  void SetUp() override {
    box_ = testing::RecordingsDir() / "box_small";
    if (!fs::exists(box_)) GTEST_SKIP() << "recordings/box_small is missing";
  }

  // box_small played `loops` times (20 frames each) as the source.
  void MakeSource(int loops) {
    testing::WriteLoopedRecording(box_, loops, tmp_.path() / "source");
    auto source = RecordingReader::Open(tmp_.path() / "source");
    ASSERT_TRUE(source.has_value()) << source.error().message;
    source_.emplace(std::move(*source));
  }

  fs::path box_;
  TempDir tmp_;
  std::optional<RecordingReader> source_;
  std::mt19937 random_{kSeed};
};

// Times measured 2026-12-02 on the shared 2-core machine (docs/reliability.md):
// record 154 s at a load of ~8 (unkilled recording 5.8 s), 78 s at ~4; run
// 1419 s at ~8 (unkilled run 121 s: each attempt is a run plus a replay of
// what it kept); replay 287 s at ~4 (unkilled replay 20 s).
TEST_F(KillLoopSlow, RecordKilledAtRandomKeepsEveryListedFrameAndReplays) {
  // 120 frames: long enough that most kills land while frames are written.
  MakeSource(6);
  const std::string exe = testing::TagsfmExe().string();
  const std::string source = "file:" + (tmp_.path() / "source").string() + "?rate=max";
  // The first run, unkilled, says how long a whole recording takes.
  const auto start = std::chrono::steady_clock::now();
  pid_t pid = testing::StartChild({exe, "record", "--source", source, "--out", (tmp_.path() / "whole").string()},
                                  tmp_.path() / "whole.log");
  ASSERT_GT(pid, 0);
  ASSERT_EQ(testing::WaitChild(pid).exit_code, 0) << ReadText(tmp_.path() / "whole.log");
  const double whole_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  ASSERT_EQ(ExpectPrefixOfSource(tmp_.path() / "whole", *source_, "unkilled"), source_->entries().size());

  std::uniform_real_distribution<double> moment(0.0, whole_s);
  int kills = 0;
  size_t frames_checked = 0;
  for (int attempt = 0; kills < kKills && attempt < 3 * kKills; ++attempt) {
    const fs::path rec = tmp_.path() / ("rec" + std::to_string(attempt));
    const std::string what = "record attempt " + std::to_string(attempt) + " (seed " + std::to_string(kSeed) + ")";
    pid = testing::StartChild({exe, "record", "--source", source, "--out", rec.string()}, rec.string() + ".log");
    ASSERT_GT(pid, 0);
    const auto outcome = testing::KillAfter(pid, std::chrono::microseconds(static_cast<long>(moment(random_) * 1e6)));
    if (outcome.killed) ++kills;
    const size_t frames = ExpectPrefixOfSource(rec, *source_, what);
    frames_checked += frames;
    if (frames > 0) ExpectReplaySucceeds(rec, tmp_.path() / ("out" + std::to_string(attempt)), what);
    fs::remove_all(rec);
    fs::remove_all(tmp_.path() / ("out" + std::to_string(attempt)));
  }
  EXPECT_GE(kills, kKills) << "too few kills landed before the recorder finished";
  std::printf("record: %d kills, %zu recorded frames checked pixel for pixel (whole run %.2f s)\n", kills,
              frames_checked, whole_s);
}

TEST_F(KillLoopSlow, RunKilledAtRandomKeepsFramesAndNeverHalfAResult) {
  // 40 frames: each kill's replay stays short.
  MakeSource(2);
  const std::string exe = testing::TagsfmExe().string();
  auto config_for = [&](const fs::path& rec) {
    const fs::path config = rec.string() + ".yaml";
    std::ofstream(config) << "capture:\n  source: file:" << (tmp_.path() / "source").string() << "?rate=max\n"
                          << "run:\n  record_dir: " << rec.string() << "\n  dashboard: 127.0.0.1:0\n";
    return config.string();
  };
  const auto start = std::chrono::steady_clock::now();
  const fs::path whole = tmp_.path() / "whole";
  pid_t pid = testing::StartChild({exe, "run", "--config", config_for(whole)}, tmp_.path() / "whole.log");
  ASSERT_GT(pid, 0);
  ASSERT_EQ(testing::WaitChild(pid).exit_code, 0) << ReadText(tmp_.path() / "whole.log");
  const double whole_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  ASSERT_EQ(ExpectWholeResults(whole / "results", "unkilled"), 4);

  std::uniform_real_distribution<double> moment(0.0, whole_s);
  int kills = 0, with_results = 0;
  for (int attempt = 0; kills < kKills && attempt < 3 * kKills; ++attempt) {
    const fs::path rec = tmp_.path() / ("rec" + std::to_string(attempt));
    const std::string what = "run attempt " + std::to_string(attempt) + " (seed " + std::to_string(kSeed) + ")";
    pid = testing::StartChild({exe, "run", "--config", config_for(rec)}, rec.string() + ".log");
    ASSERT_GT(pid, 0);
    if (testing::KillAfter(pid, std::chrono::microseconds(static_cast<long>(moment(random_) * 1e6))).killed) ++kills;
    const size_t frames = ExpectPrefixOfSource(rec, *source_, what);
    if (ExpectWholeResults(rec / "results", what) > 0) ++with_results;
    if (frames > 0) ExpectReplaySucceeds(rec, tmp_.path() / ("out" + std::to_string(attempt)), what);
    fs::remove_all(rec);
    fs::remove_all(tmp_.path() / ("out" + std::to_string(attempt)));
  }
  EXPECT_GE(kills, kKills);
  std::printf("run: %d kills, %d left result files (all whole), whole run %.2f s\n", kills, with_results, whole_s);
}

TEST_F(KillLoopSlow, ReplayKilledWhileWritingNeverLeavesHalfAResult) {
  // Kills drawn over the last 40 % of a whole replay's time, where the
  // final adjustment ends and the results are written.
  const std::string cmd = testing::TagsfmExe().string();
  const auto start = std::chrono::steady_clock::now();
  pid_t pid = testing::StartChild({cmd, "replay", box_.string(), "--out", (tmp_.path() / "whole").string()},
                                  tmp_.path() / "whole.log");
  ASSERT_GT(pid, 0);
  ASSERT_EQ(testing::WaitChild(pid).exit_code, 0) << ReadText(tmp_.path() / "whole.log");
  const double whole_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  ASSERT_EQ(ExpectWholeResults(tmp_.path() / "whole", "unkilled"), 4);

  // The window follows the machine's speed: an attempt that finished before
  // its kill becomes the new measure of a whole replay. (Run on 2026-12-02,
  // the unkilled replay took 3x longer than later ones as the load fell from
  // 9 to 4, and 18 of the first 26 moments landed after the replay had ended.)
  double current_s = whole_s;
  int kills = 0, partial_sets = 0;
  for (int attempt = 0; kills < kKills && attempt < 3 * kKills; ++attempt) {
    const fs::path out = tmp_.path() / ("out" + std::to_string(attempt));
    std::uniform_real_distribution<double> moment(0.6 * current_s, 1.05 * current_s);
    const auto attempt_start = std::chrono::steady_clock::now();
    pid = testing::StartChild({cmd, "replay", box_.string(), "--out", out.string()}, out.string() + ".log");
    ASSERT_GT(pid, 0);
    if (testing::KillAfter(pid, std::chrono::microseconds(static_cast<long>(moment(random_) * 1e6))).killed) {
      ++kills;
    } else {
      current_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - attempt_start).count();
    }
    const int present = ExpectWholeResults(out, "replay attempt " + std::to_string(attempt));
    if (present > 0 && present < 4) ++partial_sets;  // killed between two files: each whole
    fs::remove_all(out);
  }
  EXPECT_GE(kills, kKills);
  std::printf("replay: %d kills, %d between result files, whole replay %.2f s (last %.2f s)\n", kills, partial_sets,
              whole_s, current_s);
}

}  // namespace
}  // namespace tagsfm
