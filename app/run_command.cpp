// tagsfm run --config FILE: the live daemon. One thread captures and records
// every frame to disk (nothing is lost when reconstruction falls behind);
// the pipeline (pipeline/) takes the frames from a queue and its live
// feedback goes to the dashboard. At the end of the capture (Ctrl-C,
// SIGTERM, the source's end, or a camera that vanished) the final
// adjustment runs and the results are written, as `replay` of the recording
// would write them.
#include <algorithm>
#include <csignal>

#include <spdlog/spdlog.h>

#include "command_registry.h"
#include "replay_support.h"
#include "run_config.h"
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

// Sets up the daemon; on failure `*exit_code` says how (2: the config is wrong).
Result<Daemon> SetUp(const RunArgs& args, int* exit_code) {
  Daemon d;
  *exit_code = 2;
  auto config = LoadConfig(args);
  if (!config) return config.error();
  d.config = std::move(*config);
  for (const auto& warning : d.config.capture.Warnings()) spdlog::warn("{}", warning);
  *exit_code = 1;
  auto source = OpenFrameSource(d.config.capture);
  if (!source) return source.error();
  d.source = std::move(*source);
  // The config's camera and targets win; a recording played as a camera brings its own.
  RecordingInfo info = d.config.info ? *d.config.info : d.source->info();
  if (!info.camera) info.camera = d.source->info().camera;
  if (!(info.targets.size_m > 0)) return (*exit_code = 2, MakeError(args.config + ": targets: block missing (family, size_m)"));
  if (!info.camera) spdlog::warn("{}: no camera block: calibrated from the targets when capture ends, no live poses", args.config);
  auto map = ResolveTargetMap(info, std::filesystem::current_path(), "");  // config and source resolved it
  if (!map) return map.error();
  RecordingInfo recorded_info = info;
  recorded_info.targets.map.clear();  // the map file stays where it is; the recording names none
  auto writer = RecordingWriter::Create(d.config.record_dir, recorded_info);
  if (!writer) return writer.error();
  d.writer = std::move(*writer);
  const PipelineInput input{info, *map, LazyRecordingFrameLoader(d.config.record_dir), args.config};
  auto pipeline = Pipeline::Create(input, d.config.pipeline);
  if (!pipeline) return (*exit_code = 2, pipeline.error());
  d.pipeline = std::move(*pipeline);
  auto dashboard = DashboardServer::Start(d.config.dashboard);
  if (!dashboard) return dashboard.error();
  d.dashboard = std::move(*dashboard);
  return d;
}

int RunDaemon(const RunArgs& args) {
  int exit_code = 0;
  auto daemon = SetUp(args, &exit_code);
  if (!daemon) return Fail(daemon.error(), exit_code);
  Daemon& d = *daemon;
  spdlog::info("dashboard at {}; recording to {}; Ctrl-C ends the capture", d.dashboard->url(), d.config.record_dir);
  std::signal(SIGINT, RequestStop);
  std::signal(SIGTERM, RequestStop);
  WarningLog warnings;
  LiveLoopOptions loop{args.max_frames, d.config.max_queue_frames, [&](const FrameOutput& out) {
                         if (out.skipped) spdlog::warn("frame {}: {}", out.frame, *out.skipped);
                         if (!out.status) return;
                         d.dashboard->Publish(LiveStatusJson(*out.status));
                         warnings.Update(*out.status);
                       }};
  const LiveLoopSummary summary = RunLive(*d.source, *d.writer, *d.pipeline, g_stop, loop);
  std::signal(SIGINT, SIG_DFL);
  std::signal(SIGTERM, SIG_DFL);
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

void AddRunCommand(CLI::App& app, int& exit_code) {
  auto args = std::make_shared<RunArgs>();
  CLI::App* cmd = app.add_subcommand("run", "live daemon: capture, record, reconstruct and serve live feedback");
  cmd->add_option("--config", args->config,
                  "config file: capture:, camera:, targets:, run:, pipeline: blocks (see firmware_config/)")
      ->required();
  cmd->add_option("--dashboard", args->dashboard, "serve the dashboard at ADDR:PORT (default from the config, 127.0.0.1:8080)");
  cmd->add_option("--record", args->record_dir, "record to this folder instead of the config's run.record_dir");
  cmd->add_option("--frames", args->max_frames, "stop after this many frames");
  cmd->callback([args, &exit_code] { exit_code = RunDaemon(*args); });
}

const bool kRegistered = RegisterCommand("run", &AddRunCommand);

}  // namespace
}  // namespace tagsfm
