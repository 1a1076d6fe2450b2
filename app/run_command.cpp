// tagsfm run --config FILE: the live daemon. One thread captures and records
// every frame to disk (nothing is lost when reconstruction falls behind);
// the main thread detects, reconstructs and publishes live feedback on the
// dashboard. At the end of the capture (Ctrl-C, SIGTERM, the source's end, or
// a camera that vanished) the final adjustment runs and the results are
// written, as `replay` would write them for the recording.
#include <chrono>
#include <condition_variable>
#include <csignal>
#include <deque>
#include <mutex>
#include <thread>

#include <spdlog/spdlog.h>

#include "command_registry.h"
#include "feature_pipeline.h"
#include "replay_support.h"
#include "run_config.h"
#include "tagsfm/capture/recorder.h"
#include "tagsfm/dashboard/dashboard_server.h"
#include "tagsfm/feedback/live_feedback.h"
#include "tagsfm/recon/reconstructor.h"
#include "tagsfm/recon/result_writer.h"

namespace tagsfm {
namespace {

std::atomic<bool> g_stop{false};
void RequestStop(int) { g_stop.store(true); }

// Frames recorded and waiting for reconstruction. When reconstruction falls
// behind by more than `capacity` frames the oldest waiting one is dropped
// from live processing only (it is on disk; a replay sees it).
class FrameQueue {
 public:
  explicit FrameQueue(size_t capacity) : capacity_(capacity) {}
  void Push(const Frame& frame) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (frames_.size() >= capacity_) {
        frames_.pop_front();
        ++dropped_;
      }
      frames_.push_back(frame);
    }
    ready_.notify_one();
  }
  void Close() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      closed_ = true;
    }
    ready_.notify_one();
  }
  // The next frame, or nullopt once closed and drained.
  std::optional<Frame> Pop() {
    std::unique_lock<std::mutex> lock(mutex_);
    ready_.wait(lock, [&] { return closed_ || !frames_.empty(); });
    if (frames_.empty()) return std::nullopt;
    Frame frame = std::move(frames_.front());
    frames_.pop_front();
    return frame;
  }
  size_t dropped() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return dropped_;
  }

 private:
  mutable std::mutex mutex_;
  std::condition_variable ready_;
  std::deque<Frame> frames_;
  size_t capacity_;
  size_t dropped_ = 0;
  bool closed_ = false;
};

struct RunArgs {
  std::string config;
  std::string dashboard;
  std::string record_dir;
  size_t max_frames = 0;
};

double MsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

// The feature keyframes selected live, tracked from what was recorded (the
// live loop never waits for SIFT). A frame that cannot be read is left out
// with a warning.
void TrackRecordedKeyframes(const std::string& record_dir, const std::vector<DetectionSet>& keyframes,
                            FeaturePipeline& features, RunStats* stats) {
  if (keyframes.empty()) return;
  auto recording = RecordingReader::Open(record_dir);
  if (!recording) {
    spdlog::warn("features: {}", recording.error().message);
    return;
  }
  std::map<FrameId, size_t> entry_of;
  for (size_t i = 0; i < recording->entries().size(); ++i) entry_of[recording->entries()[i].frame] = i;
  for (const DetectionSet& detections : keyframes) {
    auto it = entry_of.find(detections.frame);
    auto frame = it == entry_of.end() ? Result<Frame>(MakeError("not in the recording")) : recording->LoadFrame(it->second);
    if (!frame) {
      spdlog::warn("frame {}: features: {}", detections.frame, frame.error().message);
      continue;
    }
    const auto t0 = std::chrono::steady_clock::now();
    if (Status s = features.Track(frame->gray, frame->image, detections); !s) {
      spdlog::warn("frame {}: features: {}", detections.frame, s.error().message);
    }
    stats->feature_ms.push_back(MsSince(t0));
  }
}

int RunDaemon(const RunArgs& args) {
  const auto start = std::chrono::steady_clock::now();
  auto config = ReadRunConfig(args.config);
  if (!config) {
    spdlog::error("{}", config.error().message);
    return 2;
  }
  if (!args.dashboard.empty()) config->dashboard = args.dashboard;
  if (!args.record_dir.empty()) {
    config->record_dir = args.record_dir;
    config->results_dir = (std::filesystem::path(args.record_dir) / "results").string();
  }
  for (const auto& warning : config->capture.Warnings()) spdlog::warn("{}", warning);

  auto source = OpenFrameSource(config->capture);
  if (!source) {
    spdlog::error("{}", source.error().message);
    return 1;
  }
  // The config's camera and targets win; a recording played as a camera
  // brings its own.
  RecordingInfo info = config->info ? *config->info : (*source)->info();
  if (!info.camera) info.camera = (*source)->info().camera;
  if (!info.camera) {
    spdlog::error("{}: camera: block missing; calibrate first (tagsfm calibrate on a recording)", args.config);
    return 2;
  }
  if (!(info.targets.size_m > 0)) {
    spdlog::error("{}: targets: block missing (family, size_m)", args.config);
    return 2;
  }
  std::optional<TargetCornerMap> known_map;
  if (!info.targets.map.empty()) {
    auto map = ReadTargetsCsv(info.targets.map);
    if (!map) {
      spdlog::error("{}", map.error().message);
      return 1;
    }
    known_map = std::move(*map);
  }
  RecordingInfo recorded_info = info;
  recorded_info.targets.map.clear();  // the map file stays where it is; the recording names none
  auto writer = RecordingWriter::Create(config->record_dir, recorded_info);
  if (!writer) {
    spdlog::error("{}", writer.error().message);
    return 1;
  }
  auto tracker = TagSearchForRecording(info, config->tag_search);
  if (!tracker) {
    spdlog::error("{}: targets.family: {}", args.config, tracker.error().message);
    return 2;
  }
  auto recon = Reconstructor::Create(*info.camera, info.targets, known_map, {});
  if (!recon) {
    spdlog::error("{}: {}", args.config, recon.error().message);
    return 2;
  }
  auto dashboard = DashboardServer::Start(config->dashboard);
  if (!dashboard) {
    spdlog::error("{}", dashboard.error().message);
    return 1;
  }
  spdlog::info("dashboard at {}; recording to {}; Ctrl-C ends the capture", (*dashboard)->url(), config->record_dir);

  std::signal(SIGINT, RequestStop);
  std::signal(SIGTERM, RequestStop);
  FrameQueue queue(config->max_queue_frames);
  RecordSummary summary;
  std::thread capture_thread([&] {
    summary = RecordFrames(**source, **writer, g_stop, args.max_frames, [&](const Frame& f) { queue.Push(f); });
    queue.Close();
  });

  auto features = FeaturePipeline::Create(*info.camera, info.targets, {});
  if (!features) {
    spdlog::error("{}", features.error().message);
    return 2;
  }
  std::vector<DetectionSet> feature_keyframes;  // tracked from the recording at the end

  LiveFeedback feedback(*info.camera, info.targets, config->feedback);
  RunStats stats;
  stats.mode = known_map ? "known map (" + std::to_string(known_map->size()) + " targets held fixed)"
                         : "no map: targets learned, scale from the tag size";
  std::vector<std::string> last_kinds;
  while (auto frame = queue.Pop()) {
    ++stats.frames;
    const auto t0 = std::chrono::steady_clock::now();
    // Reconstruction tells the tracker where the mapped tags will be.
    const std::map<TagId, QuadCorners> predicted =
        config->tag_search == TagSearch::kTracking ? (*recon)->PredictTagCorners(frame->index)
                                                   : std::map<TagId, QuadCorners>{};
    auto detections = (*tracker)->Track(frame->gray, frame->index, predicted);
    stats.detection_ms.push_back(MsSince(t0));
    if (!detections) {
      spdlog::warn("frame {}: {}", frame->index, detections.error().message);
      ++stats.frames_skipped;
      stats.skipped.emplace_back(frame->index, detections.error().message);
      continue;
    }
    char name[32];
    std::snprintf(name, sizeof name, "%06lld.png", static_cast<long long>(frame->index));
    stats.image_names[frame->index] = name;
    const auto t1 = std::chrono::steady_clock::now();
    const FrameReport report = (*recon)->AddFrame(*detections);
    stats.frame_latency_ms.push_back(MsSince(t1));
    if ((*features)->SelectKeyframe(*detections, report)) feature_keyframes.push_back(*detections);
    const LiveStatus& status = feedback.Update(*detections, report, frame->timestamp_ns);
    (*dashboard)->Publish(LiveStatusJson(status));
    // The terminal gets a warning when its kind appears, not every frame
    // its numbers change; the dashboard shows the current words.
    std::vector<std::string> kinds;
    for (const auto& warning : status.warnings) {
      kinds.push_back(warning.kind);
      if (std::find(last_kinds.begin(), last_kinds.end(), warning.kind) == last_kinds.end()) {
        spdlog::warn("frame {}: {}", status.frame, warning.text);
      }
    }
    last_kinds = std::move(kinds);
  }
  capture_thread.join();
  std::signal(SIGINT, SIG_DFL);
  std::signal(SIGTERM, SIG_DFL);
  for (const auto& warning : (*source)->TakeWarnings()) spdlog::warn("{}", warning);
  if (queue.dropped() > 0) {
    spdlog::warn("reconstruction fell behind: {} frames were recorded but not processed live; "
                 "`tagsfm replay {}` processes them all", queue.dropped(), config->record_dir);
  }

  ReconstructionResult result = (*recon)->Finish();
  stats.tag_search = TagSearchName(config->tag_search);
  stats.full_frame_detections = (*tracker)->stats().full_frame_detections;
  stats.tag_search_recoveries = (*tracker)->stats().recoveries;
  TrackRecordedKeyframes(config->record_dir, feature_keyframes, **features, &stats);
  const auto t_triangulate = std::chrono::steady_clock::now();
  result.feature_points = (*features)->Triangulate(result.Poses(), result.camera);
  stats.triangulation_s = MsSince(t_triangulate) / 1000.0;
  stats.runtime_s = MsSince(start) / 1000.0;
  stats.peak_rss_mb = PeakRssMb();
  const Status written = WriteResults(config->results_dir, result, stats);
  (*dashboard)->Stop();
  if (!written) {
    spdlog::error("{}", written.error().message);
    return 1;
  }
  std::printf("recorded %zu frames to %s; results in %s\n", summary.frames_written, config->record_dir.c_str(),
              config->results_dir.c_str());
  if (summary.error) {
    spdlog::error("{} ({} frames kept in {})", summary.error->message, summary.frames_written, config->record_dir);
    return 1;
  }
  return 0;
}

void AddRunCommand(CLI::App& app, int& exit_code) {
  auto args = std::make_shared<RunArgs>();
  CLI::App* cmd = app.add_subcommand("run", "live daemon: capture, record, reconstruct and serve live feedback");
  cmd->add_option("--config", args->config, "config file: capture:, camera:, targets:, run: blocks (see firmware_config/)")
      ->required();
  cmd->add_option("--dashboard", args->dashboard, "serve the dashboard at ADDR:PORT (default from the config, 127.0.0.1:8080)");
  cmd->add_option("--record", args->record_dir, "record to this folder instead of the config's run.record_dir");
  cmd->add_option("--frames", args->max_frames, "stop after this many frames");
  cmd->callback([args, &exit_code] { exit_code = RunDaemon(*args); });
}

const bool kRegistered = RegisterCommand("run", &AddRunCommand);

}  // namespace
}  // namespace tagsfm
