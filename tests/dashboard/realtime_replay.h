#pragma once
// `tagsfm replay REC --out OUT --realtime --dashboard 127.0.0.1:0` in the
// background, for the tests that watch or abuse its dashboard.
#include <chrono>
#include <cctype>
#include <cstdio>
#include <fstream>
#include <future>
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
// empty when the replay ended first or a minute passed. A plain search, not
// std::regex: GCC 12's regex fails -Werror=maybe-uninitialized in the ASan build.
inline std::string FindDashboardUrl(const std::string& text) {
  const std::string prefix = "http://127.0.0.1:";
  for (size_t at = text.find(prefix); at != std::string::npos; at = text.find(prefix, at + 1)) {
    size_t end = at + prefix.size();
    while (end < text.size() && std::isdigit(static_cast<unsigned char>(text[end]))) ++end;
    if (end > at + prefix.size() && end < text.size() && text[end] == '/') return text.substr(at, end + 1 - at);
  }
  return "";
}

inline std::string WaitForDashboardUrl(const std::filesystem::path& log, std::future<int>& replay) {
  for (auto end = std::chrono::steady_clock::now() + std::chrono::seconds(60); std::chrono::steady_clock::now() < end;) {
    if (std::string url = FindDashboardUrl(ReadText(log)); !url.empty()) return url;
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
