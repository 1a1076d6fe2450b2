#pragma once
// `tagsfm replay REC --out OUT --realtime --dashboard 127.0.0.1:0` in the
// background, for the tests that watch or abuse its dashboard.
#include <chrono>
#include <cstdio>
#include <fstream>
#include <future>
#include <regex>
#include <string>

#include "run_command.h"
#include "test_paths.h"

namespace tagsfm::testing {

inline std::future<int> StartRealtimeReplay(const std::filesystem::path& recording, const std::filesystem::path& out,
                                            const std::filesystem::path& log) {
  const std::string command = TagsfmExe().string() + " replay " + recording.string() + " --out " + out.string() +
                              " --realtime --dashboard 127.0.0.1:0";
  return std::async(std::launch::async, [command, log] { return RunCommand(command, log); });
}

// The dashboard URL the replay prints once it listens (it binds port 0);
// empty when the replay ended first or a minute passed.
inline std::string WaitForDashboardUrl(const std::filesystem::path& log, std::future<int>& replay) {
  const std::regex url(R"(http://127\.0\.0\.1:([0-9]+)/)");
  for (auto end = std::chrono::steady_clock::now() + std::chrono::seconds(60); std::chrono::steady_clock::now() < end;) {
    std::smatch m;
    const std::string text = ReadText(log);
    if (std::regex_search(text, m, url)) return m.str();
    if (replay.wait_for(std::chrono::milliseconds(20)) == std::future_status::ready) return "";
  }
  return "";
}

inline int PortOf(const std::string& url) { return std::atoi(url.substr(url.rfind(':') + 1).c_str()); }

// box_small's 20 frames forth and back `passes` times at 30 fps: a longer
// recording with smooth motion, from the bundled frames.
inline std::filesystem::path PingPongRecording(const std::filesystem::path& source, const std::filesystem::path& dir, int passes) {
  std::filesystem::create_directories(dir);
  std::filesystem::copy_file(source / "recording.yaml", dir / "recording.yaml");
  std::ofstream csv(dir / "frames.csv");
  csv << "frame,timestamp_ns,file\n";
  constexpr int kFrames = 20;
  for (int i = 0, n = passes * (kFrames - 1) + 1; i < n; ++i) {
    const int pass = i / (kFrames - 1), step = i % (kFrames - 1);
    const int original = pass % 2 == 0 ? step : kFrames - 1 - step;
    char name[32];
    std::snprintf(name, sizeof name, "frames/%06d.png", original);
    csv << i << "," << static_cast<long long>(i) * 33'333'333 << "," << (source / name).string() << "\n";
  }
  return dir;
}

}  // namespace tagsfm::testing
