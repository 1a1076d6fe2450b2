// `tagsfm record` against the kernel's vivid driver in a qemu guest
// (scripts/vivid/run_vivid.sh), checked here on the host: the formats asked
// for, frame count and rate, driver timestamps, a control applied, and an
// unplug mid-capture, and rendered frames with targets looped through the
// driver into a recording that the pipeline reconstructs. Slow (a TCG
// guest): about 1-2 minutes.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "tagsfm/capture/recording.h"

namespace tagsfm {
namespace {

namespace fs = std::filesystem;

constexpr size_t kFrames = 45;  // guest.sh's default

std::string ReadText(const fs::path& file) {
  std::ifstream in(file);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

std::string LastLine(const std::string& text) {
  std::string line, last;
  std::istringstream lines(text);
  while (std::getline(lines, line)) {
    if (!line.empty()) last = line;
  }
  return last;
}

struct Recorded {
  size_t frames = 0;
  double driver_fps = 0;     // the driver's frame clock, from its timestamps
  double delivered_fps = 0;  // frames recorded per second (lower when frames were dropped)
  double mean_grey = 0;      // of the first frame
};

constexpr double kPeriodNs = 1e9 / 30.0;

// Checks what every recording from the driver must satisfy, and measures it.
// `one_clock`: the driver was not reloaded during the recording.
Recorded CheckRecording(const fs::path& dir, bool one_clock = true) {
  Recorded out;
  auto reader = RecordingReader::Open(dir);
  EXPECT_TRUE(reader) << (reader ? "" : reader.error().message);
  if (!reader) return out;
  const auto& entries = reader->entries();
  out.frames = entries.size();
  for (size_t i = 1; i < entries.size(); ++i) {
    EXPECT_GT(entries[i].timestamp_ns, entries[i - 1].timestamp_ns) << dir << " frame " << i << ": timestamps must increase";
  }
  // vivid ticks at 30 fps; when no buffer is queued at a tick (the recorder
  // is writing a frame) that frame is dropped, so an interval spans a whole
  // number of periods, give or take the jitter of a TCG guest's timer (up to
  // ~10 ms seen): the count of periods over the span gives the driver's rate.
  double periods = 0;
  for (size_t i = 1; i < entries.size(); ++i) {
    const double dt = static_cast<double>(entries[i].timestamp_ns - entries[i - 1].timestamp_ns);
    periods += std::max(1.0, std::round(dt / kPeriodNs));
  }
  (void)one_clock;
  if (entries.size() > 1) {
    const double span = static_cast<double>(entries.back().timestamp_ns - entries.front().timestamp_ns);
    out.driver_fps = periods * 1e9 / span;
    out.delivered_fps = static_cast<double>(entries.size() - 1) * 1e9 / span;
  }
  for (size_t i = 0; i < entries.size(); i += std::max<size_t>(1, entries.size() / 5)) {
    auto frame = reader->LoadFrame(i);
    EXPECT_TRUE(frame) << dir << " frame " << i;
    if (!frame) continue;
    EXPECT_EQ(frame->image.size(), cv::Size(640, 360)) << dir;
    EXPECT_EQ(frame->image.channels(), 1) << dir << ": grey frames asked for";
    if (i == 0) out.mean_grey = cv::mean(frame->image)[0];
  }
  return out;
}

constexpr int kLoopFrames = 20;

// Renders a 1280x720 orbit of the box scene with `tagsfm synth` and writes
// its frames, raw GREY one after the other, where the guest's loop step
// feeds them into vivid's output. Returns the frames (empty on failure).
std::vector<cv::Mat> WriteLoopFeed(const fs::path& build, const fs::path& results) {
  const fs::path source = build / "vivid/loop_source";
  fs::remove_all(source);
  const std::string render = "'" + std::string(TAGSFM_EXE) + "' synth box --out '" + source.string() +
                             "' --path orbit --frames " + std::to_string(kLoopFrames) + " --samples 2 --with-map > '" +
                             (results / "loop_render.log").string() + "' 2>&1";
  if (std::system(render.c_str()) != 0) return {};
  std::vector<cv::Mat> frames;
  std::ofstream raw(results / "loop_frames.raw", std::ios::binary);
  for (int i = 0; i < kLoopFrames; ++i) {
    char name[32];
    std::snprintf(name, sizeof name, "frames/%06d.png", i);
    cv::Mat grey = cv::imread((source / name).string(), cv::IMREAD_GRAYSCALE);
    if (grey.empty() || grey.cols != 1280 || grey.rows != 720) return {};
    raw.write(reinterpret_cast<const char*>(grey.data), static_cast<std::streamsize>(grey.total()));
    frames.push_back(grey);
  }
  return frames;
}

// Which fed frame `image` is, pixel for pixel (-1: none).
int FedFrame(const cv::Mat& image, const std::vector<cv::Mat>& fed) {
  for (size_t k = 0; k < fed.size(); ++k) {
    if (image.size() == fed[k].size() && image.type() == fed[k].type() && cv::norm(image, fed[k], cv::NORM_INF) == 0) {
      return static_cast<int>(k);
    }
  }
  return -1;
}

// The kernel's vivid driver in a qemu guest (scripts/vivid/): ~30 s on a
// quiet 2-core machine, minutes under load; skipped where qemu, a static
// busybox or the kernel package cannot be had.
TEST(VividCaptureSlow, RecordsFromTheKernelDriverAndKeepsTheRecordingWhenUnplugged) {
  const fs::path build = fs::path(TAGSFM_EXE).parent_path();
  const fs::path script = fs::path(TAGSFM_RECORDINGS_DIR).parent_path() / "scripts/vivid/run_vivid.sh";
  const fs::path results = build / "vivid/results";
  fs::remove_all(results);
  fs::create_directories(results);
  const std::vector<cv::Mat> fed = WriteLoopFeed(build, results);
  ASSERT_EQ(fed.size(), static_cast<size_t>(kLoopFrames)) << ReadText(results / "loop_render.log");
  const std::string command = "bash '" + script.string() + "' '" + build.string() + "' '" + results.string() + "' > '" +
                              (results / "run.log").string() + "' 2>&1";
  const int status = std::system(command.c_str());
  const std::string log = ReadText(results / "run.log");
  if (WIFEXITED(status) && WEXITSTATUS(status) == 77) GTEST_SKIP() << LastLine(log);
  ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << log;

  EXPECT_NE(ReadText(results / "formats.txt").find("'GREY'"), std::string::npos) << "vivid offers GREY";
  for (const char* name : {"grey", "yuyv"}) {
    EXPECT_EQ(ReadText(results / (std::string(name) + ".rc")), "0\n") << name << ": " << ReadText(results / (std::string(name) + ".err"));
  }
  const Recorded grey = CheckRecording(results / "grey");
  const Recorded yuyv = CheckRecording(results / "yuyv");
  EXPECT_EQ(grey.frames, kFrames);
  EXPECT_EQ(yuyv.frames, kFrames);
  // vivid runs at the rate asked for (capture.fps 30).
  EXPECT_NEAR(grey.driver_fps, 30.0, 1.5);
  EXPECT_NEAR(yuyv.driver_fps, 30.0, 1.5);
  // capture.brightness reached the driver: it says so, and its test pattern
  // is brighter at 200 than at 60.
  EXPECT_NE(ReadText(results / "grey.brightness").find("brightness: 200"), std::string::npos);
  EXPECT_NE(ReadText(results / "yuyv.brightness").find("brightness: 60"), std::string::npos);
  EXPECT_GT(grey.mean_grey, yuyv.mean_grey + 40) << grey.mean_grey << " vs " << yuyv.mean_grey;

  // Unplugged mid-capture: exit 1, one error line naming the device and the
  // last frame, every frame before it on disk.
  EXPECT_EQ(ReadText(results / "unplug.rc"), "1\n");
  const Recorded unplug = CheckRecording(results / "unplug");
  EXPECT_GE(unplug.frames, 10u);
  const std::string err = ReadText(results / "unplug.err");
  const std::string error_line = LastLine(err);
  EXPECT_NE(error_line.find("v4l2:/dev/video0: camera lost after frame " + std::to_string(unplug.frames - 1)), std::string::npos)
      << err;
  EXPECT_NE(error_line.find(std::to_string(unplug.frames) + " frames kept in"), std::string::npos) << err;
  // libcamera runs under this kernel and finds no camera it handles.
  EXPECT_EQ(ReadText(results / "libcamera.rc"), "1\n");
  EXPECT_NE(ReadText(results / "libcamera.err").find("libcamera:0: no such camera (libcamera sees 0)"), std::string::npos)
      << ReadText(results / "libcamera.err");

  // Controls vivid lacks are said once each.
  const std::string grey_err = ReadText(results / "grey.err");
  for (const char* warning : {"has no absolute exposure control: capture.exposure_us is ignored",
                              "has no autofocus control (fixed focus?)"}) {
    const size_t at = grey_err.find(warning);
    EXPECT_NE(at, std::string::npos) << warning << "\n" << grey_err;
    EXPECT_EQ(grey_err.find(warning, at + 1), std::string::npos) << warning << "\n" << grey_err;
  }

  // Unplugged and back (vivid reloaded) with capture.reconnect_wait_s: the
  // recording goes on to the frame count asked for.
  EXPECT_EQ(ReadText(results / "replug.rc"), "0\n") << ReadText(results / "replug.err");
  const Recorded replug = CheckRecording(results / "replug", /*one_clock=*/false);
  EXPECT_EQ(replug.frames, 40u);
  EXPECT_NE(ReadText(results / "replug.err").find("it came back after"), std::string::npos) << ReadText(results / "replug.err");

  // Rendered frames with targets through the driver (vivid's HDMI output
  // looped into its input, fed at 60 fps): every recorded frame is a fed
  // frame, bit for bit, and the recording, with the render's camera and
  // target map, reconstructs: every frame registered from the targets. (The
  // recorded order jumps as the feed loops and the recorder drops frames:
  // without a map, a frame after such a jump was seen to stay unregistered.)
  EXPECT_EQ(ReadText(results / "loop.rc"), "0\n") << ReadText(results / "loop.err");
  auto loop = RecordingReader::Open(results / "loop");
  ASSERT_TRUE(loop) << loop.error().message << "\n" << ReadText(results / "loop_setup.txt");
  ASSERT_EQ(loop->entries().size(), static_cast<size_t>(kLoopFrames));
  std::set<int> seen;
  for (size_t i = 0; i < loop->entries().size(); ++i) {
    auto frame = loop->LoadFrame(i);
    ASSERT_TRUE(frame) << frame.error().message;
    const int which = FedFrame(frame->image, fed);
    EXPECT_GE(which, 0) << "recorded frame " << i << " is none of the fed frames";
    seen.insert(which);
  }
  EXPECT_GE(seen.size(), 5u) << "the feed did not move on";
  fs::copy_file(build / "vivid/loop_source/recording.yaml", results / "loop/recording.yaml",
                fs::copy_options::overwrite_existing);
  fs::copy_file(build / "vivid/loop_source/targets.csv", results / "loop/targets.csv");
  const std::string replay = "'" + std::string(TAGSFM_EXE) + "' replay '" + (results / "loop").string() + "' --out '" +
                             (results / "loop_replay").string() + "' --no-features > '" +
                             (results / "loop_replay.log").string() + "' 2>&1";
  ASSERT_EQ(std::system(replay.c_str()), 0) << ReadText(results / "loop_replay.log");
  const std::string replay_log = ReadText(results / "loop_replay.log");
  EXPECT_NE(replay_log.find("registered   20 of 20 frames"), std::string::npos) << replay_log;

  std::printf("vivid: grey %zu frames, %.2f fps recorded of the driver's %.2f; yuyv %zu, %.2f of %.2f; "
              "unplugged after %zu frames; record took %s s and %s s in the guest; looped: %zu of the %d fed frames recorded\n",
              grey.frames, grey.delivered_fps, grey.driver_fps, yuyv.frames, yuyv.delivered_fps, yuyv.driver_fps,
              unplug.frames, LastLine(ReadText(results / "grey.seconds")).c_str(),
              LastLine(ReadText(results / "yuyv.seconds")).c_str(), seen.size(), kLoopFrames);
}

}  // namespace
}  // namespace tagsfm
