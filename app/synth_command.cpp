// tagsfm synth SCENE --out REC: renders a synthetic recording with ground truth.
#include <spdlog/spdlog.h>

#include <algorithm>
#include <memory>

#include <CLI/CLI.hpp>

#include "command_registry.h"
#include "tagsfm/core/file_util.h"
#include "tagsfm/synth/synthetic_recording.h"

namespace tagsfm {
namespace {

struct SynthArgs {
  synth::SynthOptions options;
  std::string out;
  std::string distortion;
  std::string distance;
  std::vector<std::string> scale_bars;  // "A,B" each
};

// "a,b,c" -> numbers; false names nothing, the caller does.
bool ParseList(const std::string& text, std::vector<double>* values) {
  values->clear();
  for (const std::string& item : SplitCsvLine(text)) {
    double v = 0;
    if (!ParseDouble(item, &v)) return false;
    values->push_back(v);
  }
  return true;
}

int RunSynth(SynthArgs& args) {
  synth::SynthOptions& options = args.options;
  for (const std::string& bar : args.scale_bars) {
    std::vector<double> ids;
    if (!ParseList(bar, &ids) || ids.size() != 2) {
      spdlog::error("--scale-bar: expected two tag ids A,B (got '{}')", bar);
      return 2;
    }
    options.scale_bars.push_back({static_cast<int>(ids[0]), static_cast<int>(ids[1])});
  }
  if (!args.distortion.empty() && !ParseList(args.distortion, &options.distortion)) {
    spdlog::error("--distortion: expected comma-separated numbers k1,k2,p1,p2[,k3] (got '{}')", args.distortion);
    return 2;
  }
  if (!args.distance.empty()) {
    std::vector<double> range;
    if (!ParseList(args.distance, &range) || range.size() != 2) {
      spdlog::error("--distance: expected MIN,MAX in metres (got '{}')", args.distance);
      return 2;
    }
    options.min_distance = range[0];
    options.max_distance = range[1];
  }
  Result<synth::SynthSummary> summary = synth::WriteSyntheticRecording(options, args.out);
  if (!summary) {
    spdlog::error("{}", summary.error().message);
    return 1;
  }
  spdlog::info("wrote {} frames of the {} scene ({} targets) to {} in {:.1f} s ({:.2f} s per frame rendering)",
               summary->frames, options.scene, summary->targets, args.out, summary->total_seconds,
               summary->render_seconds / std::max(1, summary->frames));
  return 0;
}

void AddSynthCommand(CLI::App& app, int& exit_code) {
  auto args = std::make_shared<SynthArgs>();
  synth::SynthOptions& o = args->options;
  CLI::App* cmd = app.add_subcommand("synth", "render a synthetic recording with ground truth (docs/synth.md)");
  cmd->add_option("scene", o.scene, "box (a box on a floor, 37 targets), wall (a flat wall, 24 targets) or room (four walls seen from inside, 32 targets; its orbit turns 400 degrees and closes a loop, --distance and --azimuth do not apply)")
      ->required();
  cmd->add_option("--out", args->out, "the recording directory to create (must not exist or be empty)")->required();
  cmd->add_option("--path", o.path, "orbit (video-like arc, 30 fps) or photos (scattered views)")
      ->capture_default_str();
  cmd->add_option("--frames", o.frames, "number of frames")->capture_default_str();
  cmd->add_option("--width", o.width, "image width, pixels")->capture_default_str();
  cmd->add_option("--height", o.height, "image height, pixels")->capture_default_str();
  cmd->add_option("--fx", o.fx, "focal length, pixels (default 0.78125 x width: 65 degrees wide)");
  cmd->add_option("--fy", o.fy, "vertical focal length, pixels (default fx)");
  cmd->add_option("--distortion", args->distortion, "OpenCV radial-tangential k1,k2,p1,p2[,k3] (default none)");
  cmd->add_option("--noise", o.noise, "Gaussian image noise std, grey levels")->capture_default_str();
  cmd->add_option("--blur", o.blur, "Gaussian blur std, pixels")->capture_default_str();
  cmd->add_option("--brightness", o.brightness, "illumination factor")->capture_default_str();
  cmd->add_option("--seed", o.seed, "seed of textures, tag layout, path and noise")->capture_default_str();
  cmd->add_option("--family", o.family, "AprilTag family")->capture_default_str();
  cmd->add_option("--tag-size", o.tag_size, "tag size (edge of the black square of tag36h11), metres")
      ->capture_default_str();
  cmd->add_option("--tag-margin", o.tag_margin,
                  "white modules round the tag's black square, the surface's texture beyond (1: the official image "
                  "printed edge to edge; 2: one module of paper more)")
      ->capture_default_str();
  cmd->add_option("--print-scale", o.print_scale,
                  "tags drawn this much larger than recording.yaml says (a printer's scale error, e.g. 1.005)")
      ->capture_default_str();
  cmd->add_option("--scale-bar", args->scale_bars,
                  "A,B: a scale bar between the centres of tags A and B in recording.yaml, at their true distance; "
                  "repeatable");
  cmd->add_option("--scale-bar-sigma", o.scale_bar_sigma_m, "the scale bars' certified 1-sigma, metres")
      ->capture_default_str();
  cmd->add_option("--distance", args->distance, "MIN,MAX camera distance to the scene centre, metres (default 1.5,3)");
  cmd->add_option("--azimuth", o.max_azimuth_deg, "views span +-this many degrees about the scene's front (0: 70 for box, 35 for wall)");
  cmd->add_option("--samples", o.samples, "antialiasing samples per pixel and axis")->capture_default_str();
  cmd->add_option("--threads", o.threads, "rendering threads")->capture_default_str();
  cmd->add_flag("--with-map", o.with_map, "also write the true targets.csv and name it in recording.yaml");
  cmd->callback([args, &exit_code] { exit_code = RunSynth(*args); });
}

const bool kRegistered = RegisterCommand("synth", &AddSynthCommand);

}  // namespace
}  // namespace tagsfm
