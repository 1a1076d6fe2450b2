#include "tagsfm/synth/synthetic_recording.h"

#include <chrono>

#include <yaml-cpp/yaml.h>

#include "tagsfm/capture/recording_writer.h"
#include "tagsfm/core/csv_formats.h"
#include "tagsfm/core/file_util.h"
#include "tagsfm/synth/camera_path.h"
#include "tagsfm/synth/renderer.h"
#include "tagsfm/synth/scene_builder.h"

namespace tagsfm::synth {
namespace {

using Clock = std::chrono::steady_clock;

double SecondsSince(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

YAML::Emitter& operator<<(YAML::Emitter& out, const Eigen::Vector3d& v) {
  return out << YAML::Flow << YAML::BeginSeq << v.x() << v.y() << v.z() << YAML::EndSeq;
}

Status WriteGroundTruth(const std::filesystem::path& dir, const Scene& scene, const CameraPath& path,
                        const SynthOptions& options) {
  const std::filesystem::path truth = dir / "ground_truth";
  std::error_code ec;
  std::filesystem::create_directories(truth, ec);
  if (ec) return MakeError(truth.string() + ": cannot create (" + ec.message() + ")");
  PoseMap poses;
  for (size_t i = 0; i < path.cam_from_world.size(); ++i) poses[static_cast<FrameId>(i)] = path.cam_from_world[i];
  if (Status s = WritePosesCsv(truth / "poses.csv", poses); !s) return s;
  const TargetCornerMap targets = SceneTargets(scene);
  if (Status s = WriteTargetsCsv(truth / "targets.csv", targets); !s) return s;
  if (Status s = WriteFileAtomically(truth / "scene.yaml", SceneYamlText(scene, options)); !s) return s;
  if (options.with_map) return WriteTargetsCsv(dir / "targets.csv", targets);
  return Status::Ok();
}

// Noise differs per frame but is reproducible from the seed.
std::uint64_t NoiseSeed(std::uint64_t seed, size_t frame) {
  return (seed + 1) * 0x9E3779B97F4A7C15ULL ^ (static_cast<std::uint64_t>(frame) + 1) * 0xBF58476D1CE4E5B9ULL;
}

}  // namespace

std::string SceneYamlText(const Scene& scene, const SynthOptions& options) {
  YAML::Emitter out;
  out.SetDoublePrecision(17);
  out << YAML::BeginMap;
  out << YAML::Key << "format" << YAML::Value << "tagsfm-synth-scene/1";
  out << YAML::Key << "scene" << YAML::Value << scene.name;
  out << YAML::Key << "seed" << YAML::Value << options.seed;
  out << YAML::Key << "faces" << YAML::Value << YAML::BeginSeq;
  for (const SceneFace& face : scene.faces) {
    out << YAML::BeginMap << YAML::Key << "name" << YAML::Value << face.name;
    out << YAML::Key << "origin" << YAML::Value << face.rect.origin;
    out << YAML::Key << "edge_u" << YAML::Value << face.rect.edge_u;
    out << YAML::Key << "edge_v" << YAML::Value << face.rect.edge_v << YAML::EndMap;
  }
  out << YAML::EndSeq;
  out << YAML::Key << "tags" << YAML::Value << YAML::BeginSeq;
  for (const PlacedTag& tag : scene.tags) {
    out << YAML::Flow << YAML::BeginMap << YAML::Key << "id" << YAML::Value << tag.id;
    out << YAML::Key << "face" << YAML::Value << scene.faces[static_cast<size_t>(tag.face)].name;
    out << YAML::Key << "size_m" << YAML::Value << tag.size_m << YAML::EndMap;
  }
  out << YAML::EndSeq;
  out << YAML::Key << "render" << YAML::Value << YAML::BeginMap;
  out << YAML::Key << "family" << YAML::Value << scene.family;
  out << YAML::Key << "path" << YAML::Value << options.path;
  out << YAML::Key << "samples_per_axis" << YAML::Value << options.samples;
  out << YAML::Key << "noise" << YAML::Value << options.noise;
  out << YAML::Key << "blur" << YAML::Value << options.blur;
  out << YAML::Key << "brightness" << YAML::Value << options.brightness;
  out << YAML::Key << "tag_margin_modules" << YAML::Value << options.tag_margin;
  out << YAML::EndMap << YAML::EndMap;
  return std::string(out.c_str()) + "\n";
}

namespace {

// The scale bars asked for, at the true distance between the tags' centres.
Status AddScaleBars(const SynthOptions& options, const Scene& scene, TargetConfig* targets) {
  const TargetCornerMap truth = SceneTargets(scene);
  for (const auto& [a, b] : options.scale_bars) {
    const auto ia = truth.find(a), ib = truth.find(b);
    if (ia == truth.end() || ib == truth.end()) {
      return MakeError("--scale-bar " + std::to_string(a) + "," + std::to_string(b) + ": the scene has no tag " +
                       std::to_string(ia == truth.end() ? a : b));
    }
    const auto centre = [](const TagCorners& c) { return 0.25 * (c[0] + c[1] + c[2] + c[3]); };
    ScaleBar bar;
    bar.a.tag = a;
    bar.b.tag = b;
    bar.length_m = (centre(ia->second) - centre(ib->second)).norm();
    bar.sigma_m = options.scale_bar_sigma_m;
    targets->scale_bars.push_back(bar);
  }
  return Status::Ok();
}

}  // namespace

Result<SynthSummary> WriteSyntheticRecording(const SynthOptions& options, const std::filesystem::path& dir) {
  const Clock::time_point start = Clock::now();
  if (Status s = options.Check(); !s) return s.error();
  Result<Scene> scene = BuildScene(options);
  if (!scene) return scene.error();
  Result<CameraPath> path = MakeCameraPath(options, *scene);
  if (!path) return path.error();

  RecordingInfo info;
  info.camera = options.Camera();
  info.targets.family = options.family;
  info.targets.size_m = options.tag_size;
  if (options.with_map) info.targets.map = "targets.csv";
  if (Status s = AddScaleBars(options, *scene, &info.targets); !s) return s.error();
  Result<std::unique_ptr<RecordingWriter>> writer = RecordingWriter::Create(dir, info);
  if (!writer) return writer.error();
  // The truth goes first, so even a recording cut short has it.
  if (Status s = WriteGroundTruth(dir, *scene, *path, options); !s) return s.error();

  Result<SceneRenderer> renderer = SceneRenderer::Create(*info.camera, &*scene, options.samples, options.threads);
  if (!renderer) return renderer.error();
  const SensorOptions sensor{options.brightness, options.noise};
  SynthSummary summary;
  summary.targets = static_cast<int>(scene->tags.size());
  for (size_t i = 0; i < path->cam_from_world.size(); ++i) {
    const Clock::time_point frame_start = Clock::now();
    Frame frame;
    frame.index = static_cast<FrameId>(i);
    frame.timestamp_ns = path->timestamps_ns[i];
    frame.image = ApplySensorModel(renderer->Render(path->cam_from_world[i], options.blur), sensor, NoiseSeed(options.seed, i));
    summary.render_seconds += SecondsSince(frame_start);
    if (auto file = (*writer)->Append(frame); !file) return file.error();
    ++summary.frames;
  }
  summary.total_seconds = SecondsSince(start);
  return summary;
}

}  // namespace tagsfm::synth
