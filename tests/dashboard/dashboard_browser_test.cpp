// The dashboard in a real browser: headless Chromium (Debian's `chromium`)
// loads the page while `tagsfm replay --realtime` of a bundled recording
// serves it, watches the target count rise and a warning appear in the DOM,
// and takes a screenshot whose map area must show the targets and camera.
#include <chrono>
#include <fstream>
#include <thread>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "headless_chromium.h"
#include "realtime_replay.h"

namespace tagsfm {
namespace {

using Clock = std::chrono::steady_clock;

struct Seen {
  int targets_seen = -1;
  bool warning = false;
  int map_rects = 0;
};

Seen ReadDom(testing::HeadlessChromium& browser) {
  const auto value = browser.Evaluate(
      "JSON.stringify({mapped: document.getElementById('mapped').textContent,"
      " advice: document.getElementById('advice').className + '|' + document.getElementById('advice').textContent,"
      " rects: document.querySelectorAll('#map rect').length})");
  Seen seen;
  if (!value || !value->is_string()) return seen;
  const auto dom = nlohmann::json::parse(value->get<std::string>());
  const std::string mapped = dom["mapped"];  // "mapped / seen"
  const size_t slash = mapped.find('/');
  if (slash != std::string::npos) seen.targets_seen = std::atoi(mapped.c_str() + slash + 1);
  const std::string advice = dom["advice"];
  seen.warning = advice.rfind("warn|", 0) == 0 || advice.rfind("bad|", 0) == 0;
  seen.warning = seen.warning && advice.find("Waiting for the first frame") == std::string::npos;
  seen.map_rects = dom["rects"];
  return seen;
}

// Pixels of the map's box that differ clearly from its background, and those
// in the targets' coverage colours and the camera's blue.
struct MapPixels {
  double drawn_fraction = 0;
  int coverage_coloured = 0;
  int camera_blue = 0;
};

MapPixels CountMapPixels(const cv::Mat& shot, const cv::Rect& box) {
  MapPixels pixels;
  const cv::Mat map = shot(box & cv::Rect(0, 0, shot.cols, shot.rows));
  const cv::Vec3b background(26, 26, 26);  // #1a1a1a, BGR
  const auto near = [](const cv::Vec3b& p, int b, int g, int r) {
    return std::abs(p[0] - b) < 40 && std::abs(p[1] - g) < 40 && std::abs(p[2] - r) < 40;
  };
  int drawn = 0;
  for (int y = 0; y < map.rows; ++y) {
    for (int x = 0; x < map.cols; ++x) {
      const cv::Vec3b p = map.at<cv::Vec3b>(y, x);
      if (cv::norm(p, background, cv::NORM_INF) > 30) ++drawn;
      if (near(p, 0x44, 0x44, 0xee) || near(p, 0x33, 0xaa, 0xff) || near(p, 0x44, 0xcc, 0x44)) ++pixels.coverage_coloured;
      if (near(p, 0xff, 0xaa, 0x44)) ++pixels.camera_blue;
    }
  }
  pixels.drawn_fraction = static_cast<double>(drawn) / std::max(1, map.rows * map.cols);
  return pixels;
}

TEST(DashboardBrowserSlow, ShowsTheReplayLiveAndDrawsTheMap) {
  const std::string chromium = testing::FindChromium();
  if (chromium.empty()) GTEST_SKIP() << "chromium not found on PATH (Debian: apt-get install chromium); browser test skipped";
  const auto recording = testing::RecordingsDir() / "box_photos";  // 8 views 2 s apart, with a target map
  if (!std::filesystem::exists(recording)) GTEST_SKIP() << recording << " is missing";
  testing::TempDir tmp;
  const auto started = Clock::now();
  auto browser = testing::HeadlessChromium::Launch(chromium, 1280, 1000, tmp.path() / "profile", tmp.path() / "chromium.log");
  ASSERT_TRUE(browser) << "chromium did not start: " << testing::ReadText(tmp.path() / "chromium.log");

  const auto log = tmp.path() / "replay.log";
  auto replay = testing::StartRealtimeReplay(recording, tmp.path() / "out", log);
  const std::string url = testing::WaitForDashboardUrl(log, replay);
  ASSERT_FALSE(url.empty()) << testing::ReadText(log);
  ASSERT_TRUE(browser->Open(url));

  std::vector<int> counts;
  bool warned = false;
  while (replay.wait_for(std::chrono::milliseconds(250)) != std::future_status::ready) {
    const Seen seen = ReadDom(*browser);
    if (seen.targets_seen >= 0) counts.push_back(seen.targets_seen);
    warned = warned || seen.warning;
  }
  ASSERT_EQ(replay.get(), 0) << testing::ReadText(log);
  const Seen last = ReadDom(*browser);  // the page keeps the last status after the server stops
  counts.push_back(last.targets_seen);
  ASSERT_GE(counts.size(), 3u);
  EXPECT_LT(counts.front(), counts.back()) << "the target count never rose";
  EXPECT_GE(counts.back(), 12);  // box_photos: its 8 views see 18 of the 37 targets
  EXPECT_TRUE(warned) << "no warning appeared in the DOM";
  EXPECT_GE(last.map_rects, 12);  // every target seen is drawn

  const auto box_text = browser->Evaluate("document.getElementById('map').getAttribute('data-box')");
  const auto png = browser->ScreenshotPng();
  ASSERT_TRUE(box_text && box_text->is_string() && png);
  std::ofstream(tmp.path() / "dashboard.png", std::ios::binary) << *png;
  const std::vector<uchar> bytes(png->begin(), png->end());
  const cv::Mat shot = cv::imdecode(bytes, cv::IMREAD_COLOR);
  ASSERT_FALSE(shot.empty());
  int x = 0, y = 0, w = 0, h = 0;
  ASSERT_EQ(std::sscanf(box_text->get<std::string>().c_str(), "%d,%d,%d,%d", &x, &y, &w, &h), 4);
  ASSERT_GT(w * h, 100 * 100);
  const MapPixels pixels = CountMapPixels(shot, cv::Rect(x, y, w, h));
  // Each target is a 12 px square; half of each in a coverage colour is
  // plenty, whatever overlaps. The camera is a 7 px disc and a wedge.
  EXPECT_GT(pixels.coverage_coloured, 50 * last.map_rects) << "map area without targets";
  EXPECT_GT(pixels.camera_blue, 100) << "map area without the camera";
  EXPECT_GT(pixels.drawn_fraction, 0.01);

  // A 30 fps replay in a second tab: how many statuses reach the page and
  // how many it draws (at most 20 a second by design), and that it ends on
  // the last frame.
  const auto fast = testing::PingPongRecording(testing::RecordingsDir() / "box_small", tmp.path() / "fast", 8);
  const auto fast_log = tmp.path() / "fast.log";
  auto fast_replay = testing::StartRealtimeReplay(fast, tmp.path() / "fast_out", fast_log);
  const std::string fast_url = testing::WaitForDashboardUrl(fast_log, fast_replay);
  ASSERT_FALSE(fast_url.empty()) << testing::ReadText(fast_log);
  ASSERT_TRUE(browser->Open(fast_url));
  const auto opened = Clock::now();
  ASSERT_EQ(fast_replay.get(), 0) << testing::ReadText(fast_log);
  const double seconds = std::chrono::duration<double>(Clock::now() - opened).count();
  const auto counts_text = browser->Evaluate(
      "JSON.stringify({counts: window.dashboardCounts, frame: document.getElementById('frame').textContent})");
  ASSERT_TRUE(counts_text && counts_text->is_string());
  const auto fast_dom = nlohmann::json::parse(counts_text->get<std::string>());
  const int events = fast_dom["counts"]["events"], draws = fast_dom["counts"]["draws"];
  EXPECT_EQ(fast_dom["frame"], "152");  // 8 passes of 19 steps: frames 0..152
  EXPECT_GT(events, 0);
  EXPECT_LE(draws, 20 * seconds + 2);
  std::printf("30 fps replay: %d statuses in %.1f s reached the page (%.1f/s), %d drawn (%.1f/s)\n", events, seconds,
              events / seconds, draws, draws / seconds);

  const char* keep = std::getenv("TAGSFM_KEEP_SCREENSHOT");
  if (keep) std::filesystem::copy_file(tmp.path() / "dashboard.png", keep, std::filesystem::copy_options::overwrite_existing);
  std::printf("browser test: %.1f s, %zu DOM reads, targets seen %d -> %d, map pixels drawn %.1f %%\n",
              std::chrono::duration<double>(Clock::now() - started).count(), counts.size(), counts.front(), counts.back(),
              100 * pixels.drawn_fraction);
}

}  // namespace
}  // namespace tagsfm
