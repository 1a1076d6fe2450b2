// tagsfm calibrate REC: intrinsics from the targets for a recording without
// a camera block; writes the camera block into REC/recording.yaml.
#include <filesystem>
#include <string>

#include <spdlog/spdlog.h>

#include "command_registry.h"
#include "replay_support.h"
#include "tagsfm/capture/recording.h"
#include "tagsfm/core/file_util.h"
#include "tagsfm/recon/camera_calibration.h"

namespace tagsfm {
namespace {

struct CalibrateArgs {
  std::string recording;
  bool force = false;
  bool dry_run = false;
};

int RunCalibrate(const CalibrateArgs& args) {
  auto reader = RecordingReader::Open(args.recording);
  if (!reader) {
    spdlog::error("{}", reader.error().message);
    return 1;
  }
  const auto yaml = reader->dir() / "recording.yaml";
  if (reader->info().camera && !args.force && !args.dry_run) {
    spdlog::error("{}: already has a camera block (use --force to replace it)", yaml.string());
    return 1;
  }
  auto map = reader->LoadTargetMap();
  if (!map) {
    spdlog::error("{}", map.error().message);
    return 1;
  }
  auto detector = DetectorForRecording(reader->info());
  if (!detector) {
    spdlog::error("{}: targets.family: {}", yaml.string(), detector.error().message);
    return 1;
  }
  std::vector<DetectionSet> detections;
  int width = 0, height = 0;
  ProgressLine progress("detect", reader->entries().size());
  for (size_t i = 0; i < reader->entries().size(); ++i) {
    auto frame = reader->LoadFrame(i);
    progress.Update(i + 1);
    if (!frame) {
      spdlog::warn("skipping frame {}: {}", reader->entries()[i].frame, frame.error().message);
      continue;
    }
    width = frame->gray.cols;
    height = frame->gray.rows;
    auto d = (*detector)->Detect(frame->gray, frame->index);
    if (d) detections.push_back(std::move(*d));
  }
  progress.Done();
  auto calibration = CalibrateFromTargets(detections, reader->info().targets, width, height, *map, {});
  if (!calibration) {
    spdlog::error("{}: {}", reader->dir().string(), calibration.error().message);
    return 1;
  }
  const CameraModel& c = calibration->camera;
  spdlog::info("calibrated from {} tag views in {} frames: fx {:.2f} fy {:.2f} cx {:.2f} cy {:.2f} k1 {:.4f} k2 {:.4f}, "
               "{:.3f} px RMS",
               calibration->views, calibration->frames, c.fx, c.fy, c.cx, c.cy,
               c.distortion.size() > 0 ? c.distortion[0] : 0.0, c.distortion.size() > 1 ? c.distortion[1] : 0.0,
               calibration->rms_px);
  if (args.dry_run) return 0;
  RecordingInfo info = reader->info();
  info.camera = c;
  if (Status s = WriteFileAtomically(yaml, RecordingYamlText(info)); !s) {
    spdlog::error("{}", s.error().message);
    return 1;
  }
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
