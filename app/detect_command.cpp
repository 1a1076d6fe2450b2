// tagsfm detect IMAGE... [--family F] [--refinement R] [--no-small-tags]
// [--camera FILE]: prints each image's AprilTag detections as JSON, one array
// entry per image that could be read. --camera gives the edge fit the lens
// (TagDetectorOptions::camera), as replay does for photo sets.
#include <iostream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include "command_registry.h"
#include "tagsfm/capture/recording.h"
#include "tagsfm/detect/tag_detector.h"

namespace tagsfm {
namespace {

struct DetectArgs {
  std::vector<std::string> images;
  TagDetectorOptions options;
  std::string refinement = CornerRefinementName(TagDetectorOptions{}.refinement);
  bool small_tags = false;     // --small-tags: the pass, or an error if the family cannot have it
  bool no_small_tags = false;  // --no-small-tags
  std::string camera_file;     // --camera: recording.yaml or a run config with a camera: block
};

nlohmann::json TagsToJson(const DetectionSet& detections) {
  nlohmann::json tags = nlohmann::json::array();
  for (const TagDetection& tag : detections.tags) {
    nlohmann::json corners = nlohmann::json::array();
    for (const Eigen::Vector2d& c : tag.corners) corners.push_back({c.x(), c.y()});
    // Each corner's covariance [xx, xy, yy] in px^2 from the edge fit, null
    // where the refinement gave none.
    nlohmann::json covariances = nlohmann::json::array();
    for (const Eigen::Matrix2d& c : tag.corner_covariance) {
      covariances.push_back(c.determinant() > 0 ? nlohmann::json{c(0, 0), c(0, 1), c(1, 1)} : nlohmann::json(nullptr));
    }
    tags.push_back({{"id", tag.id},
                    {"corners", corners},
                    {"corner_covariance_px2", covariances},
                    {"decision_margin", tag.decision_margin},
                    {"hamming", tag.hamming}});
  }
  return tags;
}

int RunDetect(DetectArgs args) {
  auto refinement = ParseCornerRefinement(args.refinement);
  if (!refinement) {
    spdlog::error("--{}", refinement.error().message);
    return 2;
  }
  args.options.refinement = *refinement;
  if (!args.camera_file.empty()) {
    // The `camera:` block as recording.yaml and `tagsfm run --config` have it.
    auto info = ReadCameraAndTargets(args.camera_file);
    if (!info) {
      spdlog::error("--camera: {}", info.error().message);
      return 2;
    }
    if (!info->camera) {
      spdlog::error("--camera: {}: no camera: block", args.camera_file);
      return 2;
    }
    args.options.camera = *info->camera;
  }
  // Photos, one at a time: the small-tag pass by default where the family
  // allows it (~10 ms per image; swatbotics 236/236 instead of 216/236).
  args.options.small_tag_pass =
      args.small_tags || (!args.no_small_tags && SmallTagPassCanRead(args.options.family).ok());
  auto detector = TagDetector::Create(args.options);
  if (!detector) {
    spdlog::error("{}", detector.error().message);
    return 2;
  }
  int exit_code = 0;
  nlohmann::json out = nlohmann::json::array();
  for (size_t i = 0; i < args.images.size(); ++i) {
    const std::string& file = args.images[i];
    auto frame = LoadImageFrame(file, static_cast<FrameId>(i), 0);
    if (!frame) {
      spdlog::error("{}", frame.error().message);
      exit_code = 1;
      continue;  // the other images are still worth reporting
    }
    if (args.options.camera &&
        (frame->gray.cols != args.options.camera->width || frame->gray.rows != args.options.camera->height)) {
      spdlog::error("{}: {}x{} pixels, but the camera of {} is {}x{}", file, frame->gray.cols, frame->gray.rows,
                    args.camera_file, args.options.camera->width, args.options.camera->height);
      exit_code = 1;
      continue;
    }
    auto detections = (*detector)->Detect(frame->gray, frame->index);
    if (!detections) {
      spdlog::error("{}: {}", file, detections.error().message);
      exit_code = 1;
      continue;
    }
    out.push_back({{"file", file},
                   {"width", frame->gray.cols},
                   {"height", frame->gray.rows},
                   {"tags", TagsToJson(*detections)}});
  }
  std::cout << out.dump(2) << std::endl;
  return exit_code;
}

void AddDetectCommand(CLI::App& app, int& exit_code) {
  auto args = std::make_shared<DetectArgs>();
  CLI::App* cmd = app.add_subcommand("detect", "print the AprilTag detections of each image as JSON");
  cmd->add_option("images", args->images, "image files (PNG 8/16 bit, JPEG, PGM; grey or colour)")->required();
  cmd->add_option("--family", args->options.family, "libapriltag tag family")->capture_default_str();
  cmd->add_option("--refinement", args->refinement, "corner refinement: none, apriltag, cornersubpix, edgelinefit")
      ->capture_default_str();
  cmd->add_option("--decimate", args->options.quad_decimate, "libapriltag quad_decimate")->capture_default_str();
  cmd->add_option("--threads", args->options.threads, "libapriltag threads")->capture_default_str();
  cmd->add_option("--min-margin", args->options.min_decision_margin, "reject decodes with a lower decision margin")
      ->capture_default_str();
  cmd->add_option("--max-hamming", args->options.max_hamming, "reject decodes with more corrected bits (0..2)")
      ->capture_default_str();
  cmd->add_flag("--small-tags", args->small_tags,
                "require the small-tag pass (an error for a family it cannot read); by default it runs where the "
                "family allows (tag36h11, tag36h10, tag25h9): it also reads the small or blurred tags (about 2 px "
                "modules, or a module of blur) libapriltag finds no quad for, from OpenCV aruco's candidates "
                "(about as much again as the detection at --decimate 2; docs/detection.md)");
  cmd->add_option("--camera", args->camera_file,
                  "recording.yaml or a run config whose camera: block (intrinsics, distortion) the corner fit "
                  "uses: with lens distortion it fits the tag's edges where they are straight (docs/detection.md)");
  cmd->add_flag("--no-small-tags", args->no_small_tags, "libapriltag's tags only")->excludes("--small-tags");
  cmd->callback([args, &exit_code] { exit_code = RunDetect(*args); });
}

const bool kRegistered = RegisterCommand("detect", &AddDetectCommand);

}  // namespace
}  // namespace tagsfm
