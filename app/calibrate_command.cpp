// tagsfm calibrate REC: intrinsics from the targets for a recording without
// a camera block, as replay finds them (pipeline/: calibrated from the tag
// views, then adjusted with every frame's pose and the map), with each
// parameter's sigma; writes the camera block into REC/recording.yaml unless
// the views leave it unconstrained (recon/intrinsics_check.h).
#include <filesystem>
#include <string>

#include <spdlog/spdlog.h>

#include "command_registry.h"
#include "replay_support.h"
#include "tagsfm/core/file_util.h"
#include "tagsfm/pipeline/drivers.h"
#include "tagsfm/pipeline/target_map.h"
#include "tagsfm/recon/intrinsics_check.h"

namespace tagsfm {
namespace {

struct CalibrateArgs {
  std::string recording;
  bool force = false;
  bool dry_run = false;
  bool accept_unconstrained = false;
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
  const std::optional<IntrinsicsUncertainty> u = JudgeIntrinsics(r, {});
  if (!u) {
    return Fail(MakeError(yaml.string() + ": the intrinsics' uncertainty could not be computed (" + r.covariance_note +
                          "); nothing written"),
                1);
  }
  const std::array<double, 6>& s = u->sigma;
  spdlog::info("sigma: fx {:.2f} fy {:.2f} cx {:.2f} cy {:.2f} px, k1 {:.4f} k2 {:.4f}; distortion {:.2f} px out to "
               "{:.0f} px from the centre, where targets were seen ({:.2f} px at the image's corners)",
               s[0], s[1], s[2], s[3], s[4], s[5], u->distortion_sigma_px, u->observed_radius_px, u->distortion_sigma_corner_px);
  if (!u->unconstrained.empty()) {
    std::string why;
    for (const std::string& w : u->unconstrained) why += (why.empty() ? "" : "; ") + w;
    spdlog::log(args.accept_unconstrained ? spdlog::level::warn : spdlog::level::err,
                "the views do not constrain the intrinsics: {}. Add views with tags tilted 30-60 degrees, at several "
                "distances, and near the image's corners",
                why);
    if (!args.accept_unconstrained && !args.dry_run) {
      return Fail(MakeError(yaml.string() + ": nothing written (--accept-unconstrained writes it anyway)"), 1);
    }
  }
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
  cmd->add_flag("--accept-unconstrained", args->accept_unconstrained,
                "write the estimate even when the views leave a parameter's sigma beyond its limit");
  cmd->callback([args, &exit_code] { exit_code = RunCalibrate(*args); });
}

const bool kRegistered = RegisterCommand("calibrate", &AddCalibrateCommand);

}  // namespace
}  // namespace tagsfm
