// The whole pipeline under dashboard abuse: a realtime replay's frame
// latency with and without the abusive clients on its dashboard (the figures
// in docs/dashboard.md), and the same result either way.
#include <atomic>
#include <cstdio>
#include <fstream>
#include <map>
#include <optional>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "abusive_clients.h"
#include "realtime_replay.h"
#include "tagsfm/core/csv_formats.h"

namespace tagsfm {
namespace {

using testing::Abusers;

struct ReplayFigures {
  nlohmann::json latency_ms;
  std::map<FrameId, Rigid3d> poses;
};

ReplayFigures RealtimeReplay(const std::filesystem::path& recording, const std::filesystem::path& out, bool abuse) {
  const auto log = out.string() + ".log";
  auto replay = testing::StartRealtimeReplay(recording, out, log);
  const std::string url = testing::WaitForDashboardUrl(log, replay);
  EXPECT_FALSE(url.empty()) << testing::ReadText(log);
  std::atomic<bool> stop{false};
  std::optional<Abusers> abusers;
  if (abuse && !url.empty()) abusers.emplace(testing::PortOf(url), stop);
  EXPECT_EQ(replay.get(), 0) << testing::ReadText(log);
  stop = true;
  abusers.reset();
  ReplayFigures figures;
  figures.latency_ms = nlohmann::json::parse(testing::ReadText(out / "report.json"))["frame_latency_ms"];
  if (auto poses = ReadPosesCsv(out / "poses.csv")) figures.poses = *poses;
  return figures;
}

// The whole pipeline's frame latency in a realtime replay with and without
// the abusive clients on its dashboard (docs/dashboard.md has the figures).
TEST(DashboardAbuseSlow, ReplayFrameLatencyWithAndWithoutAbusiveClients) {
  const auto source = testing::RecordingsDir() / "box_small";
  if (!std::filesystem::exists(source)) GTEST_SKIP() << source << " is missing";
  testing::TempDir tmp;
  const auto recording = testing::PingPongRecording(source, tmp.path() / "rec", 8);  // 153 frames, 5 s
  const ReplayFigures calm = RealtimeReplay(recording, tmp.path() / "calm", false);
  const ReplayFigures abused = RealtimeReplay(recording, tmp.path() / "abused", true);
  std::printf("frame latency ms (p50/p95/max): calm %s, abused %s\n", calm.latency_ms.dump().c_str(),
              abused.latency_ms.dump().c_str());
  // The same frames through the same code: the clients change nothing in the result.
  ASSERT_GT(calm.poses.size(), 100u);
  ASSERT_EQ(abused.poses.size(), calm.poses.size());
  for (const auto& [frame, pose] : calm.poses) {
    ASSERT_TRUE(abused.poses.count(frame));
    EXPECT_LT((abused.poses.at(frame).translation - pose.translation).norm(), 1e-9) << frame;
  }
}

}  // namespace
}  // namespace tagsfm
