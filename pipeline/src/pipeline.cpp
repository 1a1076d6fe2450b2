#include "tagsfm/pipeline/pipeline.h"

#include <chrono>

#include "tagsfm/core/peak_rss.h"
#include "tagsfm/feedback/live_feedback.h"
#include "tagsfm/pipeline/feature_stage.h"
#include "tagsfm/pipeline/tag_search.h"
#include "tagsfm/recon/camera_calibration.h"
#include "tagsfm/recon/reconstructor.h"

namespace tagsfm {
namespace {

double MsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

std::string ModeOf(const std::optional<TargetCornerMap>& known_map) {
  if (known_map && !known_map->empty()) return "known map (" + std::to_string(known_map->size()) + " targets held fixed)";
  return "no map: targets learned, scale from the tag size";
}

}  // namespace

struct Pipeline::State {
  PipelineInput input;
  PipelineOptions options;
  std::chrono::steady_clock::time_point start = std::chrono::steady_clock::now();
  std::unique_ptr<TagTracker> tracker;
  std::optional<CameraModel> camera;
  std::unique_ptr<Reconstructor> recon;  // once the camera is known
  std::unique_ptr<FeatureStage> features;
  std::optional<LiveFeedback> feedback;
  // Kept until Finish: tags of frames seen before the intrinsics were known.
  std::vector<std::pair<DetectionSet, std::int64_t>> uncalibrated;
  int width = 0, height = 0;
  RunStats stats;
  std::vector<std::string> warnings;

  Status StartReconstruction(const CameraModel& known_camera, bool refine_intrinsics);
  void Reconstruct(const DetectionSet& detections, std::int64_t timestamp_ns, const Frame* frame, FrameOutput* out);
  // A frame the bootstrap held back, now a keyframe: its image read again
  // when `read_now` (else, or when that fails, at Finish).
  void AddEarlierKeyframe(const EarlierKeyframe& keyframe, bool read_now);
  void ShowCloud(LiveStatus* status) const;
  Status Calibrate();
};

Status Pipeline::State::StartReconstruction(const CameraModel& known_camera, bool refine_intrinsics) {
  camera = known_camera;
  ReconstructorOptions recon_options = options.recon;
  recon_options.refine_intrinsics = recon_options.refine_intrinsics || refine_intrinsics;
  auto created = Reconstructor::Create(known_camera, input.info.targets, input.known_map, recon_options);
  if (!created) return MakeError(input.where + ": " + created.error().message);
  recon = std::move(*created);
  if (options.features.enabled) {
    auto stage = FeatureStage::Create(known_camera, options.features, options.live_feedback);
    if (!stage) return stage.error();
    features = std::move(*stage);
  }
  if (options.live_feedback) feedback.emplace(known_camera, input.info.targets, options.feedback);
  return Status::Ok();
}

Result<std::unique_ptr<Pipeline>> Pipeline::Create(const PipelineInput& input, const PipelineOptions& options) {
  if (Status s = options.Check(); !s) return s.error();
  auto state = std::make_unique<State>();
  state->input = input;
  state->options = options;
  state->stats.mode = ModeOf(input.known_map);
  state->stats.tag_search = TagSearchName(options.tag_search);
  auto tracker = MakeTagSearch(input.info, options.tag_search, options.detector, options.tracker);
  if (!tracker) return MakeError(input.where + ": targets.family: " + tracker.error().message);
  state->tracker = std::move(*tracker);
  if (input.info.camera) {
    if (Status s = state->StartReconstruction(*input.info.camera, false); !s) return s.error();
  } else if (!input.reload) {
    return MakeError(input.where + ": no camera block, and no way to read the frames again to calibrate");
  }
  return std::unique_ptr<Pipeline>(new Pipeline(std::move(state)));
}

Pipeline::Pipeline(std::unique_ptr<State> state) : state_(std::move(state)) {}
Pipeline::~Pipeline() = default;

const std::optional<CameraModel>& Pipeline::camera() const { return state_->camera; }

std::vector<std::string> Pipeline::TakeWarnings() {
  if (state_->features) {
    for (std::string& w : state_->features->TakeWarnings()) state_->warnings.push_back(std::move(w));
  }
  return std::exchange(state_->warnings, {});
}

FrameOutput Pipeline::Skip(FrameId frame, const std::string& why) {
  ++state_->stats.frames;
  ++state_->stats.frames_skipped;
  state_->stats.skipped.emplace_back(frame, why);
  FrameOutput out;
  out.frame = frame;
  out.skipped = why;
  return out;
}

FrameOutput Pipeline::Process(const Frame& frame) {
  State& s = *state_;
  const auto t0 = std::chrono::steady_clock::now();
  // Reconstruction tells the tracker where the mapped tags will be.
  const std::map<TagId, QuadCorners> predicted =
      s.recon && s.options.tag_search == TagSearch::kTracking ? s.recon->PredictTagCorners(frame.index)
                                                              : std::map<TagId, QuadCorners>{};
  auto detections = s.tracker->Track(frame.gray, frame.index, predicted);
  if (!detections) return Skip(frame.index, detections.error().message);
  ++s.stats.frames;
  s.stats.detection_ms.push_back(MsSince(t0));
  s.stats.image_names[frame.index] = std::filesystem::path(frame.source).filename().string();
  s.width = frame.gray.cols;
  s.height = frame.gray.rows;
  FrameOutput out;
  out.frame = frame.index;
  out.timestamp_ns = frame.timestamp_ns;
  if (s.recon) {
    s.Reconstruct(*detections, frame.timestamp_ns, &frame, &out);
  } else {
    s.uncalibrated.emplace_back(*detections, frame.timestamp_ns);
  }
  out.detections = std::move(*detections);
  return out;
}

void Pipeline::State::Reconstruct(const DetectionSet& detections, std::int64_t timestamp_ns, const Frame* frame,
                                  FrameOutput* out) {
  const auto t0 = std::chrono::steady_clock::now();
  const FrameReport report = recon->AddFrame(detections);
  stats.frame_latency_ms.push_back(MsSince(t0));
  if (features) {
    for (const EarlierKeyframe& earlier : report.earlier_keyframes) AddEarlierKeyframe(earlier, frame != nullptr);
    if (features->SelectKeyframe(report)) features->AddKeyframe(frame, detections, report, recon->MappedTargetCorners());
  }
  if (feedback) {
    out->status = feedback->Update(detections, report, timestamp_ns);
    ShowCloud(&*out->status);
  }
  out->report = report;
}

void Pipeline::State::AddEarlierKeyframe(const EarlierKeyframe& keyframe, bool read_now) {
  FrameReport report;
  report.frame = keyframe.frame;
  report.registered = true;
  report.keyframe = true;
  report.cam_from_world = keyframe.cam_from_world;
  std::optional<Result<Frame>> image;
  if (read_now && input.reload) image = input.reload(keyframe.frame);
  const Frame* read = image && image->has_value() ? &**image : nullptr;
  features->AddKeyframe(read, keyframe.tags, report, recon->MappedTargetCorners());
}

void Pipeline::State::ShowCloud(LiveStatus* status) const {
  if (!features) return;
  LiveCloud cloud = features->live_cloud();
  status->feature_points = cloud.points;
  status->cloud_sample = std::move(cloud.sample);
  status->feature_keyframes = cloud.keyframes;
  status->feature_work_dropped = cloud.dropped;
}

Status Pipeline::State::Calibrate() {
  std::vector<DetectionSet> sets;
  for (const auto& [detections, timestamp] : uncalibrated) sets.push_back(detections);
  auto calibration = CalibrateFromTargets(sets, input.info.targets, width, height, input.known_map, {});
  if (!calibration) return MakeError(input.where + ": no camera block, and " + calibration.error().message);
  // Calibrated here: the final adjustment refines the intrinsics.
  if (Status s = StartReconstruction(calibration->camera, true); !s) return s;
  for (const auto& [detections, timestamp] : uncalibrated) {
    FrameOutput ignored;
    Reconstruct(detections, timestamp, nullptr, &ignored);
  }
  uncalibrated.clear();
  return Status::Ok();
}

Result<PipelineResult> Pipeline::Finish() {
  State& s = *state_;
  if (!s.recon) {
    if (Status status = s.Calibrate(); !status) return status.error();
  }
  PipelineResult out;
  Reconstructor::PointTriangulation triangulate;
  if (s.features) {
    s.features->Complete(s.input.reload);
    s.stats.feature_ms = s.features->keyframe_ms();
    s.stats.feature_work_dropped = s.features->dropped();
    if (s.stats.feature_work_dropped > 0) {
      s.warnings.push_back("features: " + std::to_string(s.stats.feature_work_dropped) +
                           " keyframes could not be processed live; done from the recording at the end");
    }
    triangulate = [&s](const PoseMap& poses, const CameraModel& camera) {
      const auto t0 = std::chrono::steady_clock::now();
      auto points = s.features->Triangulate(poses, camera, &s.stats.feature_triangulation);
      s.stats.triangulation_s += MsSince(t0) / 1000.0;  // summed: the points may be triangulated again (recon.max_points_refits)
      return points;
    };
  }
  out.reconstruction = s.recon->Finish(triangulate);
  if (s.features) s.stats.feature_keyframes_rematched = s.features->rematched();
  s.stats.full_frame_detections = s.tracker->stats().full_frame_detections;
  s.stats.tag_search_recoveries = s.tracker->stats().recoveries;
  s.stats.fine_full_frame_detections = s.tracker->stats().fine_full_frame_detections;
  s.stats.runtime_s = MsSince(s.start) / 1000.0;
  s.stats.peak_rss_mb = PeakRssMb();
  out.stats = s.stats;
  return out;
}

}  // namespace tagsfm
