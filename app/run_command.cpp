// tagsfm run --config FILE: the live daemon. One thread captures and records
// every frame to disk (nothing is lost when reconstruction falls behind);
// the pipeline (pipeline/) takes the frames from a queue and its live
// feedback goes to the dashboard. At the end of the capture (Ctrl-C,
// SIGTERM, the source's end, or a camera that vanished) the final
// adjustment runs and the results are written, as `replay` of the recording
// would write them.
#include <algorithm>
#include <csignal>
#include <variant>

#include <spdlog/spdlog.h>

#include "command_registry.h"
#include "replay_support.h"
#include "run_config.h"
#include "systemd_notifier.h"
#include "tagsfm/dashboard/dashboard_server.h"
#include "tagsfm/export/result_writer.h"
#include "tagsfm/pipeline/drivers.h"
#include "tagsfm/pipeline/target_map.h"

namespace tagsfm {
namespace {

std::atomic<bool> g_stop{false};
void RequestStop(int) { g_stop.store(true); }

struct RunArgs {
  std::string config;
  std::string check_config;
  std::string dashboard;
  std::string record_dir;
  size_t max_frames = 0;
};

Result<RunConfig> LoadConfig(const RunArgs& args) {
  auto config = ReadRunConfig(args.config);
  if (!config) return config;
  if (!args.dashboard.empty()) config->dashboard = args.dashboard;
  if (!args.record_dir.empty()) {
    config->record_dir = args.record_dir;
    config->results_dir = (std::filesystem::path(args.record_dir) / "results").string();
  }
  // Live: feedback on every frame, and features on a worker thread, so
  // that SIFT never holds up the live loop.
  config->pipeline.live_feedback = true;
  config->pipeline.features.background = true;
  return config;
}

// The terminal gets a warning when its kind appears, not every frame its
// numbers change; the dashboard shows the current words.
class WarningLog {
 public:
  void Update(const LiveStatus& status) {
    std::vector<std::string> kinds;
    for (const auto& warning : status.warnings) {
      kinds.push_back(warning.kind);
      if (std::find(last_.begin(), last_.end(), warning.kind) == last_.end()) {
        spdlog::warn("frame {}: {}", status.frame, warning.text);
      }
    }
    last_ = std::move(kinds);
  }

 private:
  std::vector<std::string> last_;
};

// What a capture needs, opened before the first frame.
struct Daemon {
  RunConfig config;
  std::unique_ptr<FrameSource> source;
  std::unique_ptr<RecordingWriter> writer;
  std::unique_ptr<Pipeline> pipeline;
  std::unique_ptr<DashboardServer> dashboard;
};

// Why the daemon could not start, and the exit code that says so.
struct Failure {
  Error error;
  int exit_code = 1;  // 2: the config is wrong; 1: the camera, the disk, the port
};

Failure ConfigFailure(Error error) { return Failure{std::move(error), 2}; }

std::variant<Daemon, Failure> SetUp(const RunArgs& args) {
  Daemon d;
  auto config = LoadConfig(args);
  if (!config) return ConfigFailure(config.error());
  d.config = std::move(*config);
  for (const auto& warning : d.config.capture.Warnings()) spdlog::warn("{}", warning);
  auto source = OpenFrameSource(d.config.capture);
  if (!source) return Failure{source.error()};
  d.source = std::move(*source);
  // The config's camera and targets win; a recording played as a camera brings its own.
  RecordingInfo info = d.config.info ? *d.config.info : d.source->info();
  if (!info.camera) info.camera = d.source->info().camera;
  if (!(info.targets.size_m > 0)) return ConfigFailure(MakeError(args.config + ": targets: block missing (family, size_m)"));
  if (!info.camera) spdlog::warn("{}: no camera block: calibrated from the targets when capture ends, no live poses", args.config);
  auto map = ResolveTargetMap(info, std::filesystem::current_path(), "");  // config and source resolved it
  if (!map) return Failure{map.error()};
  RecordingInfo recorded_info = info;
  recorded_info.targets.map.clear();  // the map file stays where it is; the recording names none
  auto writer = RecordingWriter::Create(d.config.record_dir, recorded_info);
  if (!writer) return Failure{writer.error()};
  d.writer = std::move(*writer);
  const PipelineInput input{info, *map, LazyRecordingFrameLoader(d.config.record_dir), args.config};
  auto pipeline = Pipeline::Create(input, d.config.pipeline);
  if (!pipeline) return ConfigFailure(pipeline.error());
  d.pipeline = std::move(*pipeline);
  auto dashboard = DashboardServer::Start(d.config.dashboard);
  if (!dashboard) return Failure{dashboard.error()};
  d.dashboard = std::move(*dashboard);
  return d;
}

// STATUS= for systemctl status: what a technician checks from a shell.
std::string StatusLine(const LiveStatus& s, size_t dropped_so_far) {
  char line[200];
  std::snprintf(line, sizeof line, "frame %lld, %.1f fps, %s, %d targets in view, %d mapped, %.2f m%s",
                static_cast<long long>(s.frame), s.frames_per_second, s.registered ? "tracking" : "no pose",
                s.targets_in_view, s.targets_mapped, s.depth_m,
                dropped_so_far > 0 ? (", " + std::to_string(dropped_so_far) + " skipped live").c_str() : "");
  return line;
}

// The stall after which systemd's watchdog may restart the daemon: ten
// frame intervals, and never under 10 s (a camera may pause to refocus).
std::chrono::milliseconds StallLimit(const CaptureSettings& capture) {
  return std::chrono::milliseconds(static_cast<long>(1000 * std::max(10.0, 10.0 / capture.fps)));
}

int FinishAndWrite(Daemon& d, const LiveLoopSummary& summary) {
  for (const auto& warning : d.source->TakeWarnings()) spdlog::warn("{}", warning);
  if (summary.dropped > 0) {
    spdlog::warn("reconstruction fell behind: {} frames were recorded but not processed live; "
                 "`tagsfm replay {}` processes them all", summary.dropped, d.config.record_dir);
  }
  auto result = d.pipeline->Finish();
  LogWarnings(*d.pipeline);
  d.dashboard->Stop();
  if (!result) return Fail(result.error(), 1);
  if (Status s = WriteResults(d.config.results_dir, result->reconstruction, result->stats); !s) return Fail(s.error(), 1);
  std::printf("recorded %zu frames to %s; results in %s\n", summary.recorded.frames_written, d.config.record_dir.c_str(),
              d.config.results_dir.c_str());
  if (summary.recorded.error) {
    spdlog::error("{} ({} frames kept in {})", summary.recorded.error->message, summary.recorded.frames_written,
                  d.config.record_dir);
    return 1;
  }
  return 0;
}

int RunDaemon(const RunArgs& args) {
  auto setup = SetUp(args);
  if (const Failure* failure = std::get_if<Failure>(&setup)) return Fail(failure->error, failure->exit_code);
  Daemon& d = std::get<Daemon>(setup);
  spdlog::info("dashboard at {}; recording to {}; Ctrl-C ends the capture", d.dashboard->url(), d.config.record_dir);
  SystemdNotifier systemd(StallLimit(d.config.capture));
  systemd.Ready("capturing from " + d.config.capture.source + " to " + d.config.record_dir + "; dashboard " +
                d.dashboard->url());
  std::signal(SIGINT, RequestStop);
  std::signal(SIGTERM, RequestStop);
  WarningLog warnings;
  size_t skipped = 0;
  LiveLoopOptions loop{args.max_frames, d.config.max_queue_frames, [&](const FrameOutput& out) {
                         if (out.skipped) {
                           spdlog::warn("frame {}: {}", out.frame, *out.skipped);
                           ++skipped;
                         }
                         if (!out.status) {
                           systemd.Progress("frame " + std::to_string(out.frame) + " (no live feedback yet)");
                           return;
                         }
                         d.dashboard->Publish(LiveStatusJson(*out.status));
                         warnings.Update(*out.status);
                         systemd.Progress(StatusLine(*out.status, skipped));
                       }};
  const LiveLoopSummary summary = RunLive(*d.source, *d.writer, *d.pipeline, g_stop, loop);
  std::signal(SIGINT, SIG_DFL);
  std::signal(SIGTERM, SIG_DFL);
  systemd.Stopping("capture ended after " + std::to_string(summary.recorded.frames_written) +
                   " frames; final adjustment and results");
  return FinishAndWrite(d, summary);
}

// tagsfm run --check-config FILE: every error on its own line; 0 when none.
int CheckConfig(const std::string& file) {
  const std::vector<std::string> errors = CheckRunConfigFile(file);
  for (const auto& error : errors) std::fprintf(stderr, "%s\n", error.c_str());
  if (!errors.empty()) {
    std::fprintf(stderr, "%s: %zu error%s\n", file.c_str(), errors.size(), errors.size() == 1 ? "" : "s");
    return 2;
  }
  auto config = ReadRunConfig(file);
  for (const auto& warning : config->capture.Warnings()) std::fprintf(stderr, "warning: %s\n", warning.c_str());
  std::printf("%s: valid (capture %s, %dx%d at %.4g fps; recording to %s; dashboard %s)\n", file.c_str(),
              config->capture.source.c_str(), config->capture.width, config->capture.height, config->capture.fps,
              config->record_dir.c_str(), config->dashboard.c_str());
  return 0;
}

void AddRunCommand(CLI::App& app, int& exit_code) {
  auto args = std::make_shared<RunArgs>();
  CLI::App* cmd = app.add_subcommand("run", "live daemon: capture, record, reconstruct and serve live feedback");
  auto* config = cmd->add_option("--config", args->config,
                                 "config file: capture:, camera:, targets:, run:, pipeline: blocks (see firmware_config/)");
  auto* check = cmd->add_option("--check-config", args->check_config,
                                "validate FILE, print every error (each naming its field) and exit: 0 valid, 2 not");
  config->excludes(check);
  cmd->add_option("--dashboard", args->dashboard, "serve the dashboard at ADDR:PORT (default from the config, 127.0.0.1:8080)");
  cmd->add_option("--record", args->record_dir, "record to this folder instead of the config's run.record_dir");
  cmd->add_option("--frames", args->max_frames, "stop after this many frames");
  cmd->callback([args, &exit_code] {
    if (!args->check_config.empty()) {
      exit_code = CheckConfig(args->check_config);
    } else if (args->config.empty()) {
      exit_code = Fail(MakeError("run: --config FILE is required (or --check-config FILE)"), 2);
    } else {
      exit_code = RunDaemon(*args);
    }
  });
}

const bool kRegistered = RegisterCommand("run", &AddRunCommand);

}  // namespace
}  // namespace tagsfm
