// tagsfm calibrate REC: intrinsics from the targets for a recording without
// a camera block, as replay finds them (pipeline/: calibrated from the tag
// views, then adjusted with every frame's pose and the map); writes the
// camera block into REC/recording.yaml.
#include <filesystem>
#include <string>

#include <spdlog/spdlog.h>

#include "command_registry.h"
#include "replay_support.h"
#include "tagsfm/core/file_util.h"
#include "tagsfm/pipeline/drivers.h"
#include "tagsfm/pipeline/target_map.h"

namespace tagsfm {
namespace {

struct CalibrateArgs {
  std::string recording;
  bool force = false;
  bool dry_run = false;
};

int RunCalibrate(const CalibrateArgs& args) {
  auto reader = RecordingReader::Open(args.recording);
  if (!reader) return Fail(reader.error(), 1);
  const auto yaml = reader->dir() / "recording.yaml";
  if (reader->info().camera && !args.force && !args.dry_run) {
    return Fail(MakeError(yaml.string() + ": already has a camera block (use --force to replace it)"), 1);
  }
  auto map = ResolveTargetMap(reader->info(), reader->dir(), "");
  if (!map) return Fail(map.error(), 1);
  PipelineInput input{reader->info(), *map, RecordingFrameLoader(*reader), yaml.string()};
  input.info.camera.reset();  // calibrate, whatever the file says
  PipelineOptions options;
  options.features.enabled = false;
  auto pipeline = Pipeline::Create(input, options);
  if (!pipeline) return Fail(pipeline.error(), 1);
  ProgressLine progress("detect", reader->entries().size());
  ReplayLoopOptions loop;
  loop.on_output = [](const FrameOutput& out) {
    if (out.skipped) spdlog::warn("skipping frame {}: {}", out.frame, *out.skipped);
  };
  loop.on_progress = [&](size_t done, size_t) { progress.Update(done); };
  ReplayRecording(*reader, **pipeline, loop);
  progress.Done();
  auto result = (*pipeline)->Finish();
  if (!result) return Fail(result.error(), 1);
  const ReconstructionResult& r = result->reconstruction;
  const CameraModel& c = r.camera;
  spdlog::info("calibrated and adjusted over {} target corner views: fx {:.2f} fy {:.2f} cx {:.2f} cy {:.2f} "
               "k1 {:.4f} k2 {:.4f}, {:.3f} px RMS",
               r.observations, c.fx, c.fy, c.cx, c.cy, c.distortion.size() > 0 ? c.distortion[0] : 0.0,
               c.distortion.size() > 1 ? c.distortion[1] : 0.0, r.reprojection_rms_px);
  if (args.dry_run) return 0;
  RecordingInfo info = reader->info();
  info.camera = c;
  if (Status s = WriteFileAtomically(yaml, RecordingYamlText(info)); !s) return Fail(s.error(), 1);
  return 0;
}

void AddCalibrateCommand(CLI::App& app, int& exit_code) {
  auto args = std::make_shared<CalibrateArgs>();
  CLI::App* cmd = app.add_subcommand("calibrate", "estimate the camera intrinsics from the targets; writes recording.yaml's camera block");
  cmd->add_option("recording", args->recording, "recording folder")->required();
  cmd->add_flag("--force", args->force, "replace an existing camera block");
  cmd->add_flag("--dry-run", args->dry_run, "print the estimate, write nothing");
  cmd->callback([args, &exit_code] { exit_code = RunCalibrate(*args); });
}

const bool kRegistered = RegisterCommand("calibrate", &AddCalibrateCommand);

}  // namespace
}  // namespace tagsfm
