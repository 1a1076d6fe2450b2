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
#include "tagsfm/pipeline/sfm_alone.h"
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
  int frame_step = 1;  // --no-targets: every Nth frame
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

// --no-targets: feature SfM alone (pipeline/sfm_alone.h), at arbitrary scale.
int RunSfmAloneReplay(const ReplayArgs& args) {
  if (args.realtime || !args.targets.empty() || args.no_features) {
    return Fail(MakeError("--no-targets takes neither --realtime, --targets nor --no-features"), 2);
  }
  SfmAloneOptions options;
  options.frame_step = args.frame_step;
  if (Status s = options.Check(); !s) return Fail(s.error(), 2);
  auto reader = RecordingReader::Open(args.recording);
  if (!reader) return Fail(reader.error(), 1);
  for (const auto& warning : reader->warnings()) spdlog::warn("{}", warning);
  ProgressLine progress("features", reader->entries().size());
  auto result = RunSfmAlone(*reader, options, [&](size_t done, size_t) { progress.Update(done); });
  progress.Done();
  if (!result) return Fail(result.error(), 1);
  for (const auto& [frame, why] : result->stats.skipped) spdlog::warn("skipped frame {}: {}", frame, why);
  int registered = 0;
  for (const FrameState& f : result->reconstruction.frames) {
    registered += f.registered;
    if (!f.registered) spdlog::warn("frame {}: {}", f.frame, f.reason);
  }
  if (Status s = WriteResults(args.out, result->reconstruction, result->stats); !s) return Fail(s.error(), 1);
  std::fprintf(stderr,
               "\n  SfM alone    %d of %zu frames registered, %zu points, arbitrary scale\n"
               "  runtime      %.1f s (mapping %.1f s), peak memory %.0f MB\n  results in   %s\n\n",
               registered, result->reconstruction.frames.size(), result->reconstruction.feature_points.size(),
               result->stats.runtime_s, result->stats.triangulation_s, result->stats.peak_rss_mb, args.out.c_str());
  return 0;
}

int RunReplay(const ReplayArgs& args) {
  if (args.no_targets) return RunSfmAloneReplay(args);
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
  cmd->add_flag("--no-targets", args->no_targets,
                "feature SfM alone, the SfM-only baseline: SIFT on every frame, incremental mapping with the "
                "recording's intrinsics fixed, arbitrary scale (report.json: \"scale_kind\": \"arbitrary\")");
  cmd->add_option("--frame-step", args->frame_step, "with --no-targets: every Nth frame of the recording")
      ->capture_default_str();
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
