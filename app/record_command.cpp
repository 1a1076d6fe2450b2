// tagsfm record --source SRC --out REC: capture to a recording, no reconstruction.
#include <csignal>

#include <spdlog/spdlog.h>

#include "command_registry.h"
#include "tagsfm/capture/recorder.h"

namespace tagsfm {
namespace {

std::atomic<bool> g_stop{false};
void RequestStop(int) { g_stop.store(true); }

struct RecordArgs {
  std::string source;
  std::string out;
  std::string config;
  size_t max_frames = 0;
  std::string family = "tag36h11";
  double tag_size_m = 0.0;
};

int RunRecord(const RecordArgs& args) {
  CaptureSettings settings;
  if (!args.config.empty()) {
    auto read = ReadCaptureSettings(args.config);
    if (!read) {
      spdlog::error("{}", read.error().message);
      return 2;
    }
    settings = *read;
  }
  if (!args.source.empty()) settings.source = args.source;
  for (const auto& warning : settings.Warnings()) spdlog::warn("{}", warning);
  auto source = OpenFrameSource(settings);
  if (!source) {
    spdlog::error("{}", source.error().message);
    return 1;
  }
  for (const auto& warning : (*source)->TakeWarnings()) spdlog::warn("{}", warning);  // controls, format: before capture
  // A recording keeps what its source knows (a replayed recording's camera
  // and targets); a camera's targets come from the command line.
  RecordingInfo info = (*source)->info();
  if (args.tag_size_m > 0) {
    info.targets.family = args.family;
    info.targets.size_m = args.tag_size_m;
  }
  if (!(info.targets.size_m > 0)) {
    spdlog::error("record: --tag-size is required for {} (recording.yaml needs targets.size_m)", (*source)->uri());
    return 2;
  }
  auto writer = RecordingWriter::Create(args.out, info);
  if (!writer) {
    spdlog::error("{}", writer.error().message);
    return 1;
  }
  std::signal(SIGINT, RequestStop);
  std::signal(SIGTERM, RequestStop);
  const RecordSummary summary = RecordFrames(**source, **writer, g_stop, args.max_frames);
  for (const auto& warning : (*source)->TakeWarnings()) spdlog::warn("{}", warning);
  std::signal(SIGINT, SIG_DFL);
  std::signal(SIGTERM, SIG_DFL);
  if (summary.error) {
    spdlog::error("{} ({} frames kept in {})", summary.error->message, summary.frames_written, args.out);
    return 1;
  }
  std::printf("recorded %zu frames to %s\n", summary.frames_written, args.out.c_str());
  return 0;
}

void AddRecordCommand(CLI::App& app, int& exit_code) {
  auto args = std::make_shared<RecordArgs>();
  CLI::App* cmd = app.add_subcommand("record", "capture frames to a recording, without reconstructing");
  cmd->add_option("--source", args->source, "camera URI: v4l2:/dev/video0, file:REC[?rate=max]");
  cmd->add_option("--out", args->out, "recording directory to create")->required();
  cmd->add_option("--config", args->config, "camera settings (a firmware_config/*.yaml file)");
  cmd->add_option("--frames", args->max_frames, "stop after this many frames (default: until Ctrl-C or the end)");
  cmd->add_option("--family", args->family, "tag family written to recording.yaml");
  cmd->add_option("--tag-size", args->tag_size_m, "tag black-square edge in metres, written to recording.yaml");
  cmd->callback([args, &exit_code] {
    if (args->source.empty() && args->config.empty()) {
      spdlog::error("record: give --source or --config");
      exit_code = 2;
      return;
    }
    exit_code = RunRecord(*args);
  });
}

const bool kRegistered = RegisterCommand("record", &AddRecordCommand);

}  // namespace
}  // namespace tagsfm
