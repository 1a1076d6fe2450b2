#include "tagsfm/pipeline/sfm_alone.h"

#include <chrono>
#include <filesystem>
#include <string>

#include "tagsfm/core/peak_rss.h"

namespace tagsfm {

Status SfmAloneOptions::Check() const {
  if (frame_step < 1) return MakeError("--frame-step must be >= 1");
  if (Status s = features.Check(); !s) return s;
  return mapper.Check();
}

namespace {

double MsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

// Features of every taken frame; unreadable ones are named in stats.skipped.
std::vector<KeyframeFeatures> ExtractAll(const RecordingReader& reader, const SfmAloneOptions& options, RunStats* stats,
                                         const std::function<void(size_t, size_t)>& on_progress) {
  std::vector<KeyframeFeatures> views;
  const size_t total = reader.entries().size();
  for (size_t i = 0; i < total; i += static_cast<size_t>(options.frame_step)) {
    ++stats->frames;
    const FrameEntry& entry = reader.entries()[i];
    Result<Frame> frame = reader.LoadFrame(i);
    const auto start = std::chrono::steady_clock::now();
    Result<KeyframeFeatures> features = frame ? ExtractFeatures(frame->gray, frame->image, DetectionSet{entry.frame, {}}, options.features)
                                              : Result<KeyframeFeatures>(frame.error());
    if (!features) {
      ++stats->frames_skipped;
      stats->skipped.push_back({entry.frame, features.error().message});
    } else {
      stats->feature_ms.push_back(MsSince(start));
      stats->image_names[entry.frame] = entry.file.filename().string();
      features->frame = entry.frame;
      views.push_back(std::move(*features));
    }
    if (on_progress) on_progress(i + 1, total);
  }
  return views;
}

ReconstructionResult ToReconstruction(const sfm::MapperResult& mapped, const CameraModel& camera) {
  ReconstructionResult result;
  result.camera = camera;
  const sfm::SfmModel& model = mapped.model;
  for (const sfm::SfmImage& image : model.images) {
    FrameState frame;
    frame.frame = image.frame;
    frame.registered = image.registered;
    frame.reason = image.reason;
    if (image.registered) frame.cam_from_world.Set(image.cam_from_world);
    result.frames.push_back(std::move(frame));
  }
  for (sfm::PointIdx p = 0; p < static_cast<sfm::PointIdx>(model.points.size()); ++p) {
    const sfm::SfmPoint& point = model.points[p];
    if (point.deleted || point.track.size() < 2) continue;
    const sfm::PointFit fit = sfm::FitOfPoint(model, p, camera);
    FeaturePoint out;
    out.track = static_cast<TrackId>(result.feature_points.size());
    out.position = point.xyz;
    out.rgb = point.rgb;
    out.reprojection_rms_px = fit.rms_px;
    out.max_angle_deg = fit.max_angle_deg;
    for (const sfm::Observation& obs : point.track) {
      const sfm::SfmImage& image = model.images[obs.image];
      out.observations.push_back({image.frame, image.pixels[obs.feature]});
    }
    result.feature_points.push_back(std::move(out));
  }
  const int registered = model.RegisteredImages();
  result.pose_method_counts = {{"essential_matrix", std::min(registered, 2)}, {"pnp", std::max(0, registered - 2)}};
  result.global_adjustment_converged = mapped.stats.final_adjustment_usable;
  result.points_adjusted = static_cast<int>(result.feature_points.size());
  return result;
}

}  // namespace

Result<PipelineResult> RunSfmAlone(const RecordingReader& reader, const SfmAloneOptions& options,
                                   const std::function<void(size_t, size_t)>& on_progress) {
  if (Status s = options.Check(); !s) return s.error();
  const std::string yaml = (reader.dir() / "recording.yaml").string();
  if (!reader.info().camera) {
    return MakeError(yaml + ": no camera block; SfM alone needs the intrinsics (they come from the targets: tagsfm calibrate)");
  }
  const CameraModel& camera = *reader.info().camera;
  const auto start = std::chrono::steady_clock::now();
  PipelineResult out;
  out.stats.mode = kSfmAloneMode;
  if (options.frame_step > 1) out.stats.mode += " (every " + std::to_string(options.frame_step) + "th frame)";
  const std::vector<KeyframeFeatures> views = ExtractAll(reader, options, &out.stats, on_progress);
  const auto mapping_start = std::chrono::steady_clock::now();
  Result<sfm::MapperResult> mapped = sfm::ReconstructIncremental(views, camera, options.mapper);
  if (!mapped) return MakeError(reader.dir().string() + ": SfM alone: " + mapped.error().message);
  out.reconstruction = ToReconstruction(*mapped, camera);
  out.stats.triangulation_s = MsSince(mapping_start) / 1000.0;
  out.reconstruction.global_adjustment_s = mapped->stats.mapping_s;
  out.stats.runtime_s = MsSince(start) / 1000.0;
  out.stats.peak_rss_mb = PeakRssMb();
  return out;
}

}  // namespace tagsfm
