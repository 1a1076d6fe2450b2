// tagsfm replay REC --out OUT: the pipeline on a recording, frame by frame,
// as the live daemon runs it (pipeline/), then the result files. With
// --realtime, frames are paced at their timestamps and the live feedback is
// served on the dashboard, as `run` serves it; the results are the same.
#include <cstdio>
#include <string>

#include <spdlog/spdlog.h>

#include "command_registry.h"
#include "replay_support.h"
#include "tagsfm/dashboard/dashboard_server.h"
#include "tagsfm/export/result_writer.h"
#include "tagsfm/pipeline/drivers.h"
#include "tagsfm/pipeline/target_map.h"

namespace tagsfm {
namespace {

struct ReplayArgs {
  std::string recording;
  std::string out;
  std::string targets;
  std::string config;
  bool no_features = false;
  bool no_targets = false;
  bool realtime = false;
  std::string dashboard = "127.0.0.1:8080";
  std::string tag_search;  // empty: the config's, or tracking
};

Result<PipelineOptions> ReplayOptions(const ReplayArgs& args) {
  auto options = args.config.empty() ? Result<PipelineOptions>(PipelineOptions{}) : ReadPipelineOptionsFile(args.config);
  if (!options) return options;
  if (!args.tag_search.empty()) {
    auto search = ParseTagSearch(args.tag_search);
    if (!search) return MakeError("--tag-search: " + search.error().message);
    options->tag_search = *search;
  }
  if (args.no_features) options->features.enabled = false;
  options->live_feedback = args.realtime;
  options->features.background = args.realtime;
  return options;
}

int RunReplay(const ReplayArgs& args) {
  if (args.no_targets) {
    spdlog::error("--no-targets (feature SfM alone) is not available yet: this build reconstructs from targets only");
    return 2;
  }
  auto options = ReplayOptions(args);
  if (!options) return Fail(options.error(), 2);
  auto reader = RecordingReader::Open(args.recording);
  if (!reader) return Fail(reader.error(), 1);
  for (const auto& warning : reader->warnings()) spdlog::warn("{}", warning);
  auto map = ResolveTargetMap(reader->info(), reader->dir(), args.targets);
  if (!map) return Fail(map.error(), 1);
  const PipelineInput input{reader->info(), *map, RecordingFrameLoader(*reader), (reader->dir() / "recording.yaml").string()};
  auto pipeline = Pipeline::Create(input, *options);
  if (!pipeline) return Fail(pipeline.error(), 1);

  std::unique_ptr<DashboardServer> dashboard;
  if (args.realtime) {
    auto server = DashboardServer::Start(args.dashboard);
    if (!server) return Fail(MakeError("--dashboard: " + server.error().message), 1);
    dashboard = std::move(*server);
    spdlog::info("dashboard at {}; replaying at the recording's pace", dashboard->url());
  }
  ProgressLine progress("replay", reader->entries().size());
  ReplayLoopOptions loop;
  loop.realtime = args.realtime;
  loop.on_output = [&](const FrameOutput& out) {
    if (out.skipped) spdlog::warn("skipping frame {}: {}", out.frame, *out.skipped);
    if (dashboard && out.status) dashboard->Publish(LiveStatusJson(*out.status));
    LogWarnings(**pipeline);
  };
  loop.on_progress = [&](size_t done, size_t) { progress.Update(done); };
  const ReplayLoopSummary summary = ReplayRecording(*reader, **pipeline, loop);
  progress.Done();
  if (summary.late_frames > 0) {
    spdlog::warn("{} frames were processed more than 100 ms after their time: this machine is slower than the "
                 "recording's frame rate (a live run would have dropped frames from live feedback)",
                 summary.late_frames);
  }
  auto result = (*pipeline)->Finish();
  LogWarnings(**pipeline);
  if (dashboard) dashboard->Stop();
  if (!result) return Fail(result.error(), 1);
  if (!reader->info().camera) LogCalibratedCamera(result->reconstruction);
  if (Status s = WriteResults(args.out, result->reconstruction, result->stats); !s) return Fail(s.error(), 1);
  // Progress is for terminals only; the summary is for everyone.
  PrintReplaySummary(result->reconstruction, result->stats, args.out);
  return 0;
}

void AddReplayCommand(CLI::App& app, int& exit_code) {
  auto args = std::make_shared<ReplayArgs>();
  CLI::App* cmd = app.add_subcommand("replay", "run the pipeline on a recording and write the results");
  cmd->add_option("recording", args->recording, "recording folder (recording.yaml, frames.csv, frames/)")->required();
  cmd->add_option("--out", args->out, "output folder for the results")->required();
  cmd->add_option("--targets", args->targets, "known target map (targets.csv), overriding the recording's");
  cmd->add_option("--config", args->config, "YAML file whose pipeline: block sets the pipeline's options (firmware_config/README.md)");
  cmd->add_flag("--no-features", args->no_features, "targets only (photogrammetry alone): no SIFT feature points");
  cmd->add_flag("--no-targets", args->no_targets, "feature SfM alone (not available yet)");
  cmd->add_option("--tag-search", args->tag_search,
                  "tracking (video: regions around the tags of the frames before, full frames every 15; the default) or "
                  "every_frame (photo sets: a full-frame detection on each)");
  cmd->add_flag("--realtime", args->realtime, "pace frames at their timestamps and serve the live dashboard, like run");
  cmd->add_option("--dashboard", args->dashboard, "with --realtime: serve the dashboard at ADDR:PORT (port 0: any free one)")
      ->capture_default_str();
  cmd->callback([args, &exit_code] { exit_code = RunReplay(*args); });
}

const bool kRegistered = RegisterCommand("replay", &AddReplayCommand);

}  // namespace
}  // namespace tagsfm
