#include "tagsfm/recon/reconstructor.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <numeric>

#include "tagsfm/feature/held_pose_refinement.h"
#include "tagsfm/recon/corner_weights.h"
#include "tagsfm/recon/scale_bars.h"
#include "tagsfm/recon/tag_geometry.h"
#include "tagsfm/recon/tag_initializer.h"

namespace tagsfm {

Status ReconstructorOptions::Check() const {
  if (Status s = pose.Check(); !s) return s;
  if (Status s = ba.Check(); !s) return s;
  if (!(min_tag_view_angle_deg >= 0)) return MakeError("recon.min_tag_view_angle_deg must be >= 0");
  if (max_pending_views < 1) return MakeError("recon.max_pending_views must be >= 1");
  if (!(max_tag_init_rms_px > 0)) return MakeError("recon.max_tag_init_rms_px must be > 0");
  if (remap_after_outlier_frames < 1) return MakeError("recon.remap_after_outlier_frames must be >= 1");
  if (bootstrap_max_frames < 1) return MakeError("recon.bootstrap_max_frames must be >= 1");
  if (max_retained_frames < 2) return MakeError("recon.max_retained_frames must be >= 2");
  if (!(points_refit_shift_px > 0)) return MakeError("recon.points_refit_shift_px must be > 0");
  if (max_points_refits < 0) return MakeError("recon.max_points_refits must be >= 0");
  if (tie_points_per_keyframe < 0) return MakeError("recon.tie_points_per_keyframe must be >= 0");
  if (points_threads < 1 || points_threads > 64) return MakeError("recon.points_threads must be in [1, 64]");
  if (!(bootstrap_min_angle_deg >= 0)) return MakeError("recon.bootstrap_min_angle_deg must be >= 0");
  if (!(keyframe_min_translation_ratio >= 0)) return MakeError("recon.keyframe_min_translation_ratio must be >= 0");
  if (!(keyframe_min_rotation_deg >= 0)) return MakeError("recon.keyframe_min_rotation_deg must be >= 0");
  if (!(tag_size_sigma_rel >= 0) || tag_size_sigma_rel > 0.1) {
    return MakeError("recon.tag_size_sigma_rel must be in 0..0.1");
  }
  if (!(corner_sigma_reference_px > 0) || corner_sigma_reference_px > 10) {
    return MakeError("recon.corner_sigma_reference_px must be in (0, 10]");
  }
  if (!(corner_sigma_floor_px >= 0) || corner_sigma_floor_px > 10) {
    return MakeError("recon.corner_sigma_floor_px must be in [0, 10]");
  }
  return Status::Ok();
}

Result<std::unique_ptr<Reconstructor>> Reconstructor::Create(const CameraModel& camera, const TargetConfig& targets,
                                                            const std::optional<TargetCornerMap>& known_map,
                                                            const ReconstructorOptions& options) {
  if (Status s = camera.Check(); !s) return s.error();
  if (Status s = options.Check(); !s) return s.error();
  if (!(targets.size_m > 0)) return MakeError("targets.size_m must be > 0 (got " + std::to_string(targets.size_m) + ")");
  std::unique_ptr<Reconstructor> r(new Reconstructor(camera, targets, options));
  if (known_map && !known_map->empty()) {
    for (const auto& [id, corners] : *known_map) {
      MapTag tag;
      tag.id = id;
      tag.size_m = targets.SizeOf(id);
      tag.known = true;
      tag.known_corners = corners;
      tag.world_from_tag.Set(FitTagPose(corners, tag.size_m));
      r->tags_[id] = tag;
    }
    r->started_ = true;
  }
  return r;
}

Reconstructor::Reconstructor(const CameraModel& camera, const TargetConfig& targets, const ReconstructorOptions& options)
    : camera_(camera),
      targets_(targets),
      options_(options),
      fx_(camera.fx),
      fy_(camera.fy),
      window_(std::make_unique<SlidingWindowBundleAdjuster>(options.ba, camera.fx, camera.fy)) {
  // The final adjustments (and the one with the points) weight the corners;
  // the first one, which the outliers are chosen after, does not.
  options_.ba.weight_corners = options.weight_corners;
}

Reconstructor::~Reconstructor() = default;

FrameState& Reconstructor::MakeFrameState(const DetectionSet& detections) {
  FrameState& frame = frames_.emplace_back();
  frame.frame = detections.frame;
  // A tag id seen twice in one frame cannot be told apart: neither is used.
  std::map<TagId, int> seen;
  for (const auto& d : detections.tags) ++seen[d.id];
  std::vector<Eigen::Vector2d> pixels;
  for (const auto& d : detections.tags) {
    if (seen[d.id] != 1 || !(targets_.SizeOf(d.id) > 0)) continue;
    // A NaN or infinite corner would reach every adjustment's residuals (found by degenerate_geometry_test).
    bool finite = true;
    for (const auto& c : d.corners) finite = finite && c.allFinite();
    if (!finite) continue;
    TagObservation obs;
    obs.id = d.id;
    obs.pixels = d.corners;
    obs.corner_covariance = d.corner_covariance;
    frame.tags.push_back(obs);
    pixels.insert(pixels.end(), d.corners.begin(), d.corners.end());
  }
  const std::vector<Eigen::Vector2d> normalized = camera_.PixelsToNormalized(pixels);
  for (size_t i = 0; i < frame.tags.size(); ++i) {
    for (int k = 0; k < 4; ++k) frame.tags[i].normalized[k] = normalized[4 * i + k];
  }
  return frame;
}

std::optional<Rigid3d> Reconstructor::PreviousPose(const FrameState& frame) const {
  // The registered frame nearest in sequence order (the last one while live).
  if (last_registered_ && last_registered_->frame <= frame.frame) return last_registered_->cam_from_world.ToRigid();
  const FrameState* nearest = nullptr;
  for (const auto& f : frames_) {
    if (!f.registered || &f == &frame) continue;
    if (!nearest || std::llabs(f.frame - frame.frame) < std::llabs(nearest->frame - frame.frame)) nearest = &f;
  }
  if (!nearest) return std::nullopt;
  return nearest->cam_from_world.ToRigid();
}

std::map<TagId, QuadCorners> Reconstructor::PredictTagCorners(FrameId frame,
                                                              const CornerPredictionOptions& options) const {
  if (frames_.empty() || !frames_.back().registered || last_registered_ != &frames_.back()) return {};
  const FrameState* before = nullptr;
  for (auto it = frames_.rbegin() + 1; it != frames_.rend() && !before; ++it) {
    if (it->registered && it->frame < last_registered_->frame) before = &*it;
  }
  const Rigid3d pose = ExtrapolatePose(
      last_registered_->cam_from_world.ToRigid(), last_registered_->frame,
      before ? std::optional<Rigid3d>(before->cam_from_world.ToRigid()) : std::nullopt, before ? before->frame : 0, frame);
  return ProjectMappedTags(camera_, pose, tags_, options);
}

FrameReport Reconstructor::AddFrame(const DetectionSet& detections) {
  FrameState& frame = MakeFrameState(detections);
  const size_t keyframes_before = keyframes_.size();
  FrameReport report;
  report.frame = frame.frame;
  report.tags_seen = static_cast<int>(frame.tags.size());
  if (frame.tags.empty()) {
    frame.reason = "no tags detected";
  } else if (!started_) {
    if (!TryBootstrap(frame)) frame.reason = "waiting for a second view to start the map";
  } else {
    Register(frame, true, &report);
  }
  report.registered = frame.registered;
  report.reason = frame.reason;
  report.cam_from_world = frame.cam_from_world.ToRigid();
  report.method = frame.method;
  report.fell_back = frame.fell_back;
  report.rms_px = frame.pnp_rms_px;
  report.keyframe = frame.keyframe;
  report.mapped_tags = tags_.size();
  for (size_t k = keyframes_before; k < keyframes_.size(); ++k) {
    const FrameState* earlier = keyframes_[k];
    if (earlier == &frame) continue;
    EarlierKeyframe e{earlier->frame, earlier->cam_from_world.ToRigid(), DetectionSet{earlier->frame, {}}};
    for (const TagObservation& obs : earlier->tags) {
      TagDetection tag;
      tag.id = obs.id;
      tag.corners = obs.pixels;
      e.tags.tags.push_back(tag);
    }
    report.earlier_keyframes.push_back(std::move(e));
  }
  std::sort(report.earlier_keyframes.begin(), report.earlier_keyframes.end(),
            [](const EarlierKeyframe& a, const EarlierKeyframe& b) { return a.frame < b.frame; });
  RetainOrThin(frames_.size() - 1);
  return report;
}

void Reconstructor::RetainOrThin(size_t index) {
  FrameState& frame = frames_[index];
  if (frame.keyframe || frame.tags.empty()) return;
  if (index % retain_stride_ != 0 && !IsHeld(frame)) {
    GiveBackViews(&frame);
    return;
  }
  if (++retained_ <= static_cast<size_t>(options_.max_retained_frames)) return;
  // Over the budget: keep every second one of those kept, evenly in time,
  // and from now on every second one of those to come.
  retain_stride_ *= 2;
  retained_ = 0;
  for (size_t i = 0; i < frames_.size(); ++i) {
    FrameState& f = frames_[i];
    if (f.keyframe || f.tags.empty()) continue;
    if (i % retain_stride_ != 0 && !IsHeld(f)) {
      GiveBackViews(&f);
    } else {
      ++retained_;
    }
  }
}

bool Reconstructor::IsHeld(const FrameState& frame) const {
  auto holds = [&frame](const std::vector<FrameState*>& views) {
    return std::find(views.begin(), views.end(), &frame) != views.end();
  };
  if (holds(bootstrap_buffer_)) return true;
  for (const auto& [id, views] : pending_) {
    if (holds(views)) return true;
  }
  for (const auto& [id, views] : outlier_runs_) {
    if (holds(views)) return true;
  }
  return false;
}

void Reconstructor::GiveBackViews(FrameState* frame) {
  frame->tags.clear();
  frame->tags.shrink_to_fit();
  frame->thinned = true;
  ++frames_thinned_;
}

bool Reconstructor::TryBootstrap(FrameState& frame) {
  std::map<TagId, double> sizes;
  for (const auto& obs : frame.tags) sizes[obs.id] = targets_.SizeOf(obs.id);
  for (FrameState* earlier : bootstrap_buffer_) {
    const auto boot = BootstrapFromTwoViews(*earlier, frame, sizes, fx_, fy_);
    if (!boot || boot->view_angle_deg < options_.bootstrap_min_angle_deg || boot->rms_px > TagInitLimitPx()) {
      continue;
    }
    anchor_ = boot->anchor;
    for (const auto& [id, world_from_tag] : boot->world_from_tag) {
      MapTag tag;
      tag.id = id;
      tag.size_m = targets_.SizeOf(id);
      tag.anchor = id == boot->anchor;
      tag.world_from_tag.Set(world_from_tag);
      tags_[id] = tag;
    }
    for (auto [state, pose] : {std::pair{earlier, boot->first_cam_from_world}, std::pair{&frame, boot->second_cam_from_world}}) {
      state->registered = true;
      state->reason.clear();
      state->method = PoseMethod::kIppe;
      state->cam_from_world.Set(pose);
      state->keyframe = true;
      CountMethod(*state);
      window_->AddKeyframe(*state, tags_);
      keyframes_.push_back(state);
    }
    last_registered_ = &frame;
    started_ = true;
    SolveWindow();
    for (FrameState* state : {earlier, &frame}) {
      for (const auto& obs : state->tags) {
        if (!tags_.count(obs.id)) pending_[obs.id].push_back(state);
      }
    }
    RegisterBuffered(&frame);
    return true;
  }
  bootstrap_buffer_.push_back(&frame);
  if (bootstrap_buffer_.size() < static_cast<size_t>(options_.bootstrap_max_frames)) return false;
  StartFromBuffer();
  return frame.registered;
}

void Reconstructor::StartFromBuffer() {
  // No two views to decide with: the view with the largest tag starts the map.
  FrameState* best = nullptr;
  double best_area = -1;
  for (FrameState* f : bootstrap_buffer_) {
    for (const auto& obs : f->tags) {
      const double area = (obs.pixels[2] - obs.pixels[0]).norm() * (obs.pixels[3] - obs.pixels[1]).norm();
      if (area > best_area) {
        best_area = area;
        best = f;
      }
    }
  }
  if (!best) return;
  StartMapFromOneView(*best);
  RegisterBuffered(best);
}

void Reconstructor::StartMapFromOneView(FrameState& frame) {
  const TagObservation* anchor = nullptr;
  double best_area = -1;
  for (const auto& obs : frame.tags) {
    const double area = (obs.pixels[2] - obs.pixels[0]).norm() * (obs.pixels[3] - obs.pixels[1]).norm();
    if (area > best_area) {
      best_area = area;
      anchor = &obs;
    }
  }
  const auto candidates = TagPoseCandidates(anchor->normalized, targets_.SizeOf(anchor->id));
  if (candidates.empty()) return;
  MapTag tag;
  tag.id = anchor->id;
  tag.size_m = targets_.SizeOf(anchor->id);
  tag.anchor = true;
  tags_[tag.id] = tag;
  anchor_ = tag.id;
  started_ = true;
  frame.registered = true;
  frame.reason.clear();
  frame.method = PoseMethod::kIppe;
  frame.cam_from_world.Set(candidates.front());
  frame.keyframe = true;
  CountMethod(frame);
  window_->AddKeyframe(frame, tags_);
  keyframes_.push_back(&frame);
  last_registered_ = &frame;
  for (const auto& obs : frame.tags) {
    if (!tags_.count(obs.id)) pending_[obs.id].push_back(&frame);
  }
}

void Reconstructor::RegisterBuffered(const FrameState* except) {
  std::vector<FrameState*> buffered;
  buffered.swap(bootstrap_buffer_);
  for (FrameState* f : buffered) {
    if (f == except || f->registered) continue;
    FrameReport ignored;
    Register(*f, true, &ignored);
  }
}

void Reconstructor::CountMethod(const FrameState& frame) {
  ++method_counts_[PoseMethodName(frame.method)];
  if (frame.fell_back) ++method_counts_["fallback"];
}

// 3D corners and their normalised observations, four per tag used.
struct Reconstructor::FrameCorrespondences {
  std::vector<Eigen::Vector3d> points;
  std::vector<Eigen::Vector2d> observed;
  std::vector<TagObservation*> used;  // one per 4 correspondences

  void Add(const TagCorners& corners, TagObservation* obs) {
    for (int k = 0; k < 4; ++k) {
      points.push_back(corners[k]);
      observed.push_back(obs->normalized[k]);
    }
    used.push_back(obs);
  }
};

Reconstructor::FrameCorrespondences Reconstructor::MappedCorners(FrameState& frame, bool adjust, FrameReport* report) {
  FrameCorrespondences mapped;
  for (auto& obs : frame.tags) {
    obs.outlier = false;
    auto it = tags_.find(obs.id);
    if (it == tags_.end()) continue;
    mapped.Add(it->second.CornersInWorld(), &obs);
    ++report->tags_used;
  }
  if (mapped.points.empty() && adjust) {
    // The chain of views would break here: put the frame's tags that earlier
    // registered frames saw into the map now, from the views there are (the
    // adjustments refine them as more views come).
    std::vector<TagId> forced = MapPendingTagsNow(frame);
    for (TagId id : forced) {
      TagObservation* obs = nullptr;
      for (auto& o : frame.tags) {
        if (o.id == id) obs = &o;
      }
      mapped.Add(tags_.at(id).CornersInWorld(), obs);
      ++report->tags_used;
    }
    for (TagId id : forced) window_->AddTag(tags_.at(id));
  }
  return mapped;
}

PoseResult Reconstructor::SolveFramePose(const FrameState& frame, const FrameCorrespondences& mapped) {
  PoseEstimatorOptions pose_options = options_.pose;
  pose_options.corner_sigma_px = std::max(pose_options.corner_sigma_px, corner_noise_px_);
  PoseResult pose = EstimatePose(mapped.points, mapped.observed, fx_, fy_, PreviousPose(frame), pose_options);
  if (pose.registered) return pose;
  // Noisier corners than the fixed limits allow? Measure this frame's
  // corner noise from its tags' shapes and check against that instead.
  const double sigma = MeasureFrameNoisePx(frame);
  if (sigma > pose_options.corner_sigma_px) {
    RememberNoise(sigma);
    pose_options.corner_sigma_px = sigma;
    pose = EstimatePose(mapped.points, mapped.observed, fx_, fy_, PreviousPose(frame), pose_options);
  }
  return pose;
}

void Reconstructor::Register(FrameState& frame, bool adjust, FrameReport* report) {
  const FrameCorrespondences mapped = MappedCorners(frame, adjust, report);
  if (mapped.points.empty()) {
    frame.reason = "none of its " + std::to_string(frame.tags.size()) + " tags is in the map yet";
    return;
  }
  const PoseResult pose = SolveFramePose(frame, mapped);
  if (!pose.registered) {
    frame.reason = pose.reason;
    return;
  }
  // Tags with a corner outside the pose's inliers stay out of the adjustments.
  std::vector<bool> inlier(mapped.points.size(), false);
  for (int i : pose.inliers) inlier[i] = true;
  for (size_t t = 0; t < mapped.used.size(); ++t) {
    TagObservation* used = mapped.used[t];
    for (int k = 0; k < 4; ++k) used->outlier = used->outlier || !inlier[4 * t + k];
    if (used->outlier) report->outlier_tags.push_back(used->id);
  }
  frame.registered = true;
  frame.reason.clear();
  frame.cam_from_world.Set(pose.cam_from_world);
  frame.method = pose.method;
  frame.fell_back = pose.fell_back;
  frame.pnp_rms_px = pose.rms_px;
  CountMethod(frame);
  if (!last_registered_ || last_registered_->frame <= frame.frame) last_registered_ = &frame;
  if (!adjust) return;

  report->remapped_tags = RemapDisagreeingTags(frame);
  std::vector<TagId> added;
  report->tags_added = MapPendingTags(frame, &added);
  if (IsKeyframe(frame, !added.empty())) AddKeyframe(frame, added);
}

void Reconstructor::AddKeyframe(FrameState& frame, const std::vector<TagId>& added) {
  frame.keyframe = true;
  for (TagId id : added) window_->AddTag(tags_.at(id));
  window_->AddKeyframe(frame, tags_);
  keyframes_.push_back(&frame);
  SolveWindow();
}

void Reconstructor::SolveWindow() {
  const WindowSolution solution = window_->Solve();
  for (const auto& [id, pose] : solution.cam_from_world) {
    if (FrameState* keyframe = FindKeyframe(id)) keyframe->cam_from_world = pose;
  }
  for (const auto& [id, pose] : solution.world_from_tag) tags_.at(id).world_from_tag = pose;
}

FrameState* Reconstructor::FindKeyframe(FrameId id) {
  // The window holds the latest keyframes: each is a few steps from the end.
  auto keyframe = std::find_if(keyframes_.rbegin(), keyframes_.rend(), [id](const FrameState* k) { return k->frame == id; });
  return keyframe == keyframes_.rend() ? nullptr : *keyframe;
}

double Reconstructor::TagInitLimitPx() const {
  return std::max(options_.max_tag_init_rms_px, options_.pose.rms_sigmas * std::sqrt(2.0) * corner_noise_px_);
}

double Reconstructor::MeasureFrameNoisePx(const FrameState& frame) const {
  std::vector<std::array<Eigen::Vector2d, 4>> corners;
  std::vector<double> sizes;
  for (const auto& obs : frame.tags) {
    corners.push_back(obs.normalized);
    sizes.push_back(targets_.SizeOf(obs.id));
  }
  return MeasureCornerNoisePx(corners, sizes, fx_, fy_);
}

void Reconstructor::RememberNoise(double sigma_px) {
  // The median of the last few measurements: one odd frame does not set it.
  noise_measurements_.push_back(sigma_px);
  if (noise_measurements_.size() > 15) noise_measurements_.pop_front();
  std::vector<double> sorted(noise_measurements_.begin(), noise_measurements_.end());
  std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
  corner_noise_px_ = sorted[sorted.size() / 2];
}

std::array<Eigen::Vector2d, 4> Reconstructor::NormalizedCornerErrors(const Rigid3d& cam_from_world, const MapTag& tag,
                                                                     const TagObservation& obs) {
  const TagCorners corners = tag.CornersInWorld();
  std::array<Eigen::Vector2d, 4> errors;
  for (int k = 0; k < 4; ++k) {
    const Eigen::Vector3d p = cam_from_world * corners[k];
    errors[k] = p.z() > 0 ? Eigen::Vector2d(p.hnormalized() - obs.normalized[k]) : Eigen::Vector2d::Constant(INFINITY);
  }
  return errors;
}

int Reconstructor::FlagOutlierObservations(const std::vector<FrameState*>& frames) {
  // Against the current poses and map: a tag view whose worst corner is off
  // by more than outlier_sigmas robust sigmas of all corners (and at least
  // min_outlier_px) is left out, as EstimatePose does within one frame.
  std::vector<double> errors;
  std::vector<std::pair<TagObservation*, double>> worst;
  for (FrameState* frame : frames) {
    const Rigid3d cam_from_world = frame->cam_from_world.ToRigid();
    for (auto& obs : frame->tags) {
      obs.outlier = false;
      auto it = tags_.find(obs.id);
      if (it == tags_.end()) continue;
      double max_error = 0;
      for (const Eigen::Vector2d& e : NormalizedCornerErrors(cam_from_world, it->second, obs)) {
        const double error = std::hypot(fx_ * e.x(), fy_ * e.y());
        errors.push_back(error);
        max_error = std::max(max_error, error);
      }
      worst.emplace_back(&obs, max_error);
    }
  }
  if (errors.empty()) return 0;
  std::nth_element(errors.begin(), errors.begin() + errors.size() / 2, errors.end());
  const double robust_sigma = errors[errors.size() / 2] / 1.1774;  // median 2D error = sigma sqrt(2 ln 2)
  const double threshold = std::max(options_.pose.min_outlier_px, options_.pose.outlier_sigmas * robust_sigma);
  int flagged = 0;
  for (auto& [obs, error] : worst) {
    obs->outlier = !(error <= threshold);
    flagged += obs->outlier;
  }
  return flagged;
}

int Reconstructor::MapPendingTags(FrameState& frame, std::vector<TagId>* added) {
  for (const auto& obs : frame.tags) {
    if (tags_.count(obs.id)) continue;
    auto& views = pending_[obs.id];
    views.push_back(&frame);
    // Bounded: the latest views say the most about where the tag is now.
    if (views.size() > 20) views.erase(views.begin());
    std::vector<TagView> tag_views;
    for (FrameState* f : views) tag_views.push_back({f, f->Find(obs.id)});
    const double size = targets_.SizeOf(obs.id);
    // A cheap look first: is the angle between the views wide enough yet?
    const auto single = TagPoseCandidates(obs.normalized, size);
    if (single.empty()) continue;
    const Eigen::Vector3d centre = frame.cam_from_world.ToRigid().Inverse() * single.front().translation;
    const bool enough = MaxViewAngleDeg(tag_views, centre) >= options_.min_tag_view_angle_deg ||
                        static_cast<int>(views.size()) >= options_.max_pending_views;
    if (!enough) continue;
    const auto init = InitializeTag(tag_views, size, fx_, fy_);
    if (!init || init->rms_px > TagInitLimitPx()) continue;
    MapTag tag;
    tag.id = obs.id;
    tag.size_m = size;
    tag.world_from_tag.Set(init->world_from_tag);
    tags_[obs.id] = tag;
    pending_.erase(obs.id);
    added->push_back(obs.id);
  }
  return static_cast<int>(added->size());
}

std::vector<TagId> Reconstructor::RemapDisagreeingTags(FrameState& frame) {
  std::vector<TagId> moved;
  for (const auto& obs : frame.tags) {
    auto tag = tags_.find(obs.id);
    if (tag == tags_.end() || tag->second.known || tag->second.anchor) continue;
    std::vector<FrameState*>& run = outlier_runs_[obs.id];
    if (!obs.outlier) {
      run.clear();
      continue;
    }
    run.push_back(&frame);
    if (static_cast<int>(run.size()) < options_.remap_after_outlier_frames) continue;
    std::vector<TagView> views;
    for (const FrameState* f : run) views.push_back({f, f->Find(obs.id)});
    const MapTag& mapped = tag->second;
    const auto init = InitializeTag(views, mapped.size_m, fx_, fy_);
    const double now_rms = TagPoseRmsPx(mapped.world_from_tag.ToRigid(), mapped.size_m, views, fx_, fy_);
    // Only a pose that fits these views as a new tag must, and fits them
    // better than the mapped one; else the run goes on growing (bounded).
    if (init && init->rms_px <= TagInitLimitPx() && !(now_rms <= init->rms_px)) {
      tag->second.world_from_tag.Set(init->world_from_tag);
      for (FrameState* f : run) {
        for (TagObservation& o : f->tags) o.outlier = o.outlier && o.id != obs.id;
      }
      std::vector<FrameId> fitted;
      for (const FrameState* f : run) fitted.push_back(f->frame);
      for (FrameId outlier : window_->ReplaceTag(tag->second, fitted)) {
        if (FrameState* keyframe = FindKeyframe(outlier)) {
          for (TagObservation& o : keyframe->tags) o.outlier = o.outlier || o.id == obs.id;
        }
      }
      moved.push_back(obs.id);
      run.clear();
    } else if (static_cast<int>(run.size()) > 4 * options_.remap_after_outlier_frames) {
      run.erase(run.begin());
    }
  }
  tags_remapped_ += static_cast<int>(moved.size());
  return moved;
}

std::vector<TagId> Reconstructor::MapPendingTagsNow(const FrameState& frame) {
  // Each candidate pose of a pending tag (the IPPE pair of each earlier
  // view) implies, with the pair of this frame, a pose of this frame. Views
  // of a walk around a scene change little from one to the next, so the
  // candidate whose implied pose is nearest the last registered frame's wins.
  std::vector<TagId> added;
  const std::optional<Rigid3d> previous = PreviousPose(frame);
  for (const auto& obs : frame.tags) {
    auto it = pending_.find(obs.id);
    if (it == pending_.end() || it->second.empty()) continue;
    std::vector<TagView> views;
    for (FrameState* f : it->second) views.push_back({f, f->Find(obs.id)});
    const double size = targets_.SizeOf(obs.id);
    const auto here = TagPoseCandidates(obs.normalized, size);
    // Each recent view's IPPE pair, checked against the view it came from,
    // and the pose refined over all views (the cameras fixed), checked
    // against all. On a room walk, two views' poses from few tags each left
    // every candidate of the next tag 3-4 px off in the other view: checked
    // against all views, the chain broke there. The global adjustment
    // settles such disagreements; the frame's own pose is still checked.
    std::vector<std::pair<Rigid3d, std::vector<TagView>>> candidates;
    for (size_t v = views.size() > 3 ? views.size() - 3 : 0; v < views.size(); ++v) {
      const Rigid3d world_from_cam = views[v].frame->cam_from_world.ToRigid().Inverse();
      for (const Rigid3d& cam_from_tag : TagPoseCandidates(views[v].observation->normalized, size)) {
        candidates.push_back({world_from_cam * cam_from_tag, {views[v]}});
      }
    }
    if (views.size() >= 2) {
      if (const auto refined = InitializeTag(views, size, fx_, fy_)) candidates.push_back({refined->world_from_tag, views});
    }
    std::optional<Rigid3d> best;
    double best_score = INFINITY;
    for (const auto& [world_from_tag, checked_views] : candidates) {
      {
        const double rms = TagPoseRmsPx(world_from_tag, size, checked_views, fx_, fy_);
        if (!(rms <= TagInitLimitPx())) continue;
        for (const Rigid3d& here_from_tag : here) {
          const Rigid3d implied = here_from_tag * world_from_tag.Inverse();
          const double score = previous ? RotationAngleDeg(implied.rotation, previous->rotation) : rms;
          if (score < best_score) {
            best_score = score;
            best = world_from_tag;
          }
        }
      }
    }
    if (!best) continue;
    MapTag tag;
    tag.id = obs.id;
    tag.size_m = size;
    tag.world_from_tag.Set(*best);
    tags_[obs.id] = tag;
    pending_.erase(it);
    added.push_back(obs.id);
  }
  return added;
}

bool Reconstructor::IsKeyframe(const FrameState& frame, bool added_tags) const {
  if (added_tags || keyframes_.empty()) return true;
  const Rigid3d current = frame.cam_from_world.ToRigid();
  std::vector<double> depths;
  for (const auto& obs : frame.tags) {
    auto it = tags_.find(obs.id);
    if (it != tags_.end()) depths.push_back((current * TagCenter(it->second.CornersInWorld())).z());
  }
  if (depths.empty()) return false;
  std::nth_element(depths.begin(), depths.begin() + depths.size() / 2, depths.end());
  const double min_translation = options_.keyframe_min_translation_ratio * depths[depths.size() / 2];
  // Against every keyframe, not only the last: a camera walked back over
  // ground it has covered adds views that are already there.
  for (const FrameState* keyframe : keyframes_) {
    const Rigid3d pose = keyframe->cam_from_world.ToRigid();
    if (RotationAngleDeg(current.rotation, pose.rotation) < options_.keyframe_min_rotation_deg &&
        (current.Center() - pose.Center()).norm() < min_translation) {
      return false;
    }
  }
  return true;
}

// Finish, phase by phase: the map completed from what is still waiting, the
// frames registered late, a first adjustment where drift or unregistered
// frames ask for it, the final adjustment, and the statistics.
ReconstructionResult Reconstructor::Finish(const PointTriangulation& triangulate) {
  // Too few frames to wait for a second view: start from the best one.
  if (!started_ && !bootstrap_buffer_.empty()) StartFromBuffer();
  MapWaitingTags();
  RegisterLateFrames();
  std::vector<FrameState*> registered = RegisteredFrames();
  AdjustFirstAndRetry(&registered);
  ReconstructionResult result;
  result.tags_remapped = tags_remapped_;
  result.window_solves_failed = window_->failed_solves();
  result.frames_thinned = frames_thinned_;
  if (options_.final_adjustment && !registered.empty()) AdjustFinally(registered, &result);
  ApplyScale(&registered, &result);
  if (triangulate && !registered.empty()) {
    TriangulateAndAdjust(registered, triangulate, &result);
    RefitScaleBars(&registered, &result);
  }
  CollectReprojectionStatistics(registered, &result);
  result.camera = camera_;
  result.frames.assign(frames_.begin(), frames_.end());
  result.tags = tags_;
  result.pose_method_counts = method_counts_;
  result.anchor_tag = anchor_;
  result.unmapped_tags = UnmappedTagReasons();
  return result;
}

std::map<TagId, std::string> Reconstructor::UnmappedTagReasons() const {
  std::map<TagId, int> frames_seen, registered_seen;
  for (const FrameState& f : frames_) {
    for (const TagObservation& t : f.tags) {
      if (tags_.count(t.id)) continue;
      ++frames_seen[t.id];
      registered_seen[t.id] += f.registered ? 1 : 0;
    }
  }
  std::map<TagId, std::string> reasons;
  for (const auto& [id, seen] : frames_seen) {
    const auto known = unmapped_reasons_.find(id);
    if (known != unmapped_reasons_.end() && pending_.count(id)) {
      reasons[id] = known->second;
    } else if (seen == 1) {
      reasons[id] = "seen in one frame only";
    } else if (registered_seen[id] == 0) {
      reasons[id] = "seen in " + std::to_string(seen) + " frames, none of them registered";
    } else {
      reasons[id] = "seen in " + std::to_string(seen) + " frames (" + std::to_string(registered_seen[id]) +
                    " registered) but never waiting to be mapped (its views were outliers or ambiguous)";
    }
  }
  return reasons;
}

void Reconstructor::MapWaitingTags() {
  // Tags still waiting get the views they have when these span enough angle
  // (or when there is a single view of everything): a tag seen from one
  // direction only would add its poorly known depth to the map.
  int registered_frames = 0;
  for (const auto& f : frames_) registered_frames += f.registered;
  std::vector<TagId> waiting;
  for (const auto& [id, views] : pending_) waiting.push_back(id);
  for (TagId id : waiting) {
    auto it = pending_.find(id);
    std::vector<TagView> views;
    for (FrameState* f : it->second) views.push_back({f, f->Find(id)});
    const auto init = InitializeTag(views, targets_.SizeOf(id), fx_, fy_);
    if (!init) {
      unmapped_reasons_[id] = "no pose fits its " + std::to_string(views.size()) + " registered views";
      continue;
    }
    if (init->rms_px > TagInitLimitPx()) {
      char why[128];
      std::snprintf(why, sizeof why, "its best pose fits its %zu registered views at %.2f px RMS (limit %.2f)",
                    views.size(), init->rms_px, TagInitLimitPx());
      unmapped_reasons_[id] = why;
      continue;
    }
    if (views.size() == 1 && registered_frames >= 2) {
      unmapped_reasons_[id] = "seen in one registered frame only";
      continue;
    }
    const double span_deg = MaxViewAngleDeg(views, init->world_from_tag.translation);
    if (registered_frames >= 2 && span_deg < options_.min_tag_view_angle_deg) {
      char why[128];
      std::snprintf(why, sizeof why, "its %zu registered views span %.1f deg (at least %.1f needed)", views.size(),
                    span_deg, options_.min_tag_view_angle_deg);
      unmapped_reasons_[id] = why;
      continue;
    }
    MapTag tag;
    tag.id = id;
    tag.size_m = targets_.SizeOf(id);
    tag.world_from_tag.Set(init->world_from_tag);
    tags_[id] = tag;
    pending_.erase(it);
  }
}

void Reconstructor::RegisterLateFrames() {
  // Frames that came before their tags were mapped get a second chance.
  for (auto& frame : frames_) {
    if (frame.registered || frame.tags.empty() || !started_) continue;
    FrameReport ignored;
    Register(frame, false, &ignored);
  }
}

std::vector<FrameState*> Reconstructor::RegisteredFrames() {
  std::vector<FrameState*> registered;
  for (auto& frame : frames_) {
    if (frame.registered) registered.push_back(&frame);
  }
  return registered;
}

void Reconstructor::AdjustFirstAndRetry(std::vector<FrameState*>* registered) {
  // A first adjustment spreads the drift of a loop; frames whose pose check
  // failed against the drifting map get a last chance against the adjusted
  // one. With learned tags it also comes before the outliers are chosen:
  // before it, the drift of the incremental map alone put 10 % of the views
  // of a 40-photo box scene over 1 px (after it, only a tag cut by the image
  // border). So it starts from every view.
  bool retry = false;
  for (const auto& f : frames_) retry = retry || (!f.registered && !f.tags.empty());
  bool learned = false;
  for (const auto& [id, tag] : tags_) learned = learned || !tag.known;
  if (!options_.final_adjustment || registered->empty() || !(retry || learned) || !started_) return;
  if (learned) {
    for (FrameState* frame : *registered) {
      for (auto& obs : frame->tags) obs.outlier = false;
    }
  }
  BundleAdjusterOptions first = options_.ba;
  first.compute_covariance = false;
  first.weight_corners = false;
  AdjustGlobally(*registered, &tags_, fx_, fy_, first);
  for (auto& frame : frames_) {
    if (frame.registered || frame.tags.empty()) continue;
    FrameReport ignored;
    Register(frame, false, &ignored);
    if (frame.registered) registered->push_back(&frame);
  }
  // Tags still waiting were refused against the incremental poses. Where a
  // loop closes, a tag seen at its start and its end has views on both
  // sides of the drift, and no pose fits them all until the adjustment has
  // spread it: on a room walk of 400 degrees three such tags fitted their
  // views at 2.7-5.5 px before it.
  if (!pending_.empty()) MapWaitingTags();
}

// The corners' noise against their covariance (FitCornerNoise) from the
// residuals of the unweighted adjustment and its inliers.
CornerNoiseModel Reconstructor::EstimateCornerNoise(const std::vector<FrameState*>& registered) const {
  std::vector<std::pair<double, double>> variance_and_squared_error;
  int parameters = 0, corners_used = 0;
  for (const FrameState* frame : registered) {
    const Rigid3d cam_from_world = frame->cam_from_world.ToRigid();
    bool used = false;
    for (const TagObservation& obs : frame->tags) {
      auto it = tags_.find(obs.id);
      if (it == tags_.end() || obs.outlier) continue;
      used = true;
      const std::array<Eigen::Vector2d, 4> errors = NormalizedCornerErrors(cam_from_world, it->second, obs);
      for (int k = 0; k < 4; ++k) {
        ++corners_used;
        if (!(obs.corner_covariance[k].determinant() > 0)) continue;
        const Eigen::Vector2d& e = errors[k];
        const double squared = fx_ * fx_ * e.x() * e.x() + fy_ * fy_ * e.y() * e.y();
        variance_and_squared_error.emplace_back(0.5 * obs.corner_covariance[k].trace(), squared);
      }
    }
    parameters += used ? 6 : 0;
  }
  for (const auto& [id, tag] : tags_) parameters += tag.known || tag.anchor ? 0 : 6;
  if (corners_used == 0) return {};
  const double redundancy = std::max(0.1, 1.0 - parameters / (2.0 * corners_used));
  return FitCornerNoise(std::move(variance_and_squared_error), redundancy);
}

void Reconstructor::SetWeights(const std::vector<FrameState*>& registered, ReconstructionResult* result) {
  const CornerNoiseModel noise = EstimateCornerNoise(registered);
  result->corner_noise = noise;
  // Relative weights need the floor in the covariance's own units. Where
  // it is 20x a typical corner's sigma the weights would all be ~1: the
  // covariance says nothing of these errors (scale ~0: a real room whose
  // lens the model lacks), and every corner counts the same.
  const double floor_in_c = noise.scale > 0 ? noise.floor_px / noise.scale : INFINITY;
  if (!(floor_in_c < 20 * options_.corner_sigma_reference_px)) return;
  const double floor = std::max(options_.corner_sigma_floor_px, floor_in_c);
  // The reference grows with the floor, so that a typical corner still
  // weighs ~1 and the robust losses keep their scale in pixels.
  const double reference = std::hypot(options_.corner_sigma_reference_px, floor);
  for (FrameState* frame : registered) {
    for (TagObservation& obs : frame->tags) SetCornerWeights(obs.corner_covariance, camera_, reference, floor, &obs);
  }
}

void Reconstructor::AdjustFinally(const std::vector<FrameState*>& registered, ReconstructionResult* result) {
  result->outlier_observations = FlagOutlierObservations(registered);
  if (options_.weight_corners) SetWeights(registered, result);
  // Intrinsics are refined for the model the calibration estimates (pinhole, k1 k2).
  const bool refine = options_.refine_intrinsics && camera_.kind == CameraModel::Kind::kPinhole &&
                      camera_.distortion.size() <= 5 &&
                      (camera_.distortion.size() < 3 || (camera_.distortion[2] == 0 && camera_.distortion[3] == 0)) &&
                      (camera_.distortion.size() < 5 || camera_.distortion[4] == 0);
  GlobalAdjustmentSummary summary = AdjustGlobally(registered, &tags_, fx_, fy_, options_.ba, refine ? &camera_ : nullptr);
  // Square pixels unless the data say otherwise: fx and fy adjusted freely
  // first; when they differ by no more than 3 sigma of their difference,
  // again with fy tied to fx (one focal length: its sigma falls, and weak
  // data can no longer make the pixels oblong).
  if (refine && summary.intrinsics_covariance) {
    const Eigen::Matrix<double, 6, 6>& c = *summary.intrinsics_covariance;
    const double difference_sigma = std::sqrt(std::max(0.0, c(0, 0) + c(1, 1) - 2 * c(0, 1)));
    if (std::abs(camera_.fx - camera_.fy) <= 3 * difference_sigma) {
      BundleAdjusterOptions square = options_.ba;
      square.square_pixels = true;
      summary = AdjustGlobally(registered, &tags_, camera_.fx, camera_.fy, square, &camera_);
      square_pixels_ = true;
    }
  }
  result->intrinsics_refined = refine;
  result->square_pixels = square_pixels_;
  result->global_adjustment_converged = summary.converged;
  result->covariance = summary.covariance;
  result->covariance_note = summary.covariance_note;
  result->intrinsics_covariance = summary.intrinsics_covariance;
  result->global_adjustment_s = summary.solve_s;
  result->covariance_s = summary.covariance_s;
}

void Reconstructor::ApplyScale(std::vector<FrameState*>* registered, ReconstructionResult* result) {
  result->scale.sigma_rel = options_.tag_size_sigma_rel;
  if (targets_.scale_bars.empty()) return;
  const bool known_map = std::any_of(tags_.begin(), tags_.end(), [](const auto& t) { return t.second.known; });
  Result<MapScale> fit = FitScaleBars(targets_.scale_bars, MappedTargetCorners(), result->covariance);
  if (!fit) {
    result->scale.note = fit.error().message + "; the scale comes from the tag sizes";
    return;
  }
  if (known_map) {
    result->scale.bars = fit->bars;
    result->scale.note = "a known map fixes the scale: the scale bars are only checked against it";
    return;
  }
  ScaleScene(fit->scale, registered, &tags_, &result->covariance);
  result->scale = *fit;
}

void Reconstructor::RefitScaleBars(std::vector<FrameState*>* registered, ReconstructionResult* result) {
  // The points' rays moved the tags (and so the bars' lengths in the map)
  // and sharpened their covariance: the bars fitted on that map give the
  // scale it needs, with the sigma it has. The correction is a factor near
  // 1 on top of the first fit's.
  if (result->scale.source != "scale bars" || result->points_adjusted == 0) return;
  Result<MapScale> fit = FitScaleBars(targets_.scale_bars, MappedTargetCorners(), result->covariance);
  if (!fit) return;  // the same bars were fitted before the points; their tags are still mapped
  const double correction = fit->scale;
  ScaleScene(correction, registered, &tags_, &result->covariance);
  for (FeaturePoint& p : result->feature_points) {
    p.position *= correction;
    p.covariance *= correction * correction;
  }
  // Each bar's length as the map at the nominal sizes would give it, so
  // that factor x length - certified is still its residual.
  for (ScaleBarCheck& bar : fit->bars) {
    bar.measured_m /= result->scale.scale;
    bar.sigma_m /= result->scale.scale;
  }
  fit->scale = result->scale.scale * correction;
  result->scale = *fit;
}

namespace {

// The tie points of the adjustment with the points. Each keyframe's image
// is cut in 8 x 8 cells, and the points are taken in order of views (most
// first), then of reprojection error (least first), while a cell they are
// seen in has fewer than per_keyframe / 64: points spread over the image
// fix a pose that points taken by views alone leave less well (box_small:
// 95.3 % of the points within 2 mm instead of 95.7; docs/features.md).
// Indices into `points`, ascending; all of them for per_keyframe 0.
std::vector<size_t> TiePoints(const std::vector<FeaturePoint>& points, int per_keyframe, const CameraModel& camera) {
  std::vector<size_t> order(points.size());
  std::iota(order.begin(), order.end(), size_t{0});
  if (per_keyframe <= 0) return order;
  std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) {
    const size_t va = points[a].observations.size(), vb = points[b].observations.size();
    if (va != vb) return va > vb;
    return points[a].reprojection_rms_px < points[b].reprojection_rms_px;
  });
  constexpr int kCells = 8;
  const int per_cell = std::max(1, per_keyframe / (kCells * kCells));
  auto cell_of = [&](const std::pair<FrameId, Eigen::Vector2d>& view) {
    const int x = std::clamp(static_cast<int>(view.second.x() * kCells / camera.width), 0, kCells - 1);
    const int y = std::clamp(static_cast<int>(view.second.y() * kCells / camera.height), 0, kCells - 1);
    return std::make_pair(view.first, y * kCells + x);
  };
  std::map<std::pair<FrameId, int>, int> taken;
  std::vector<size_t> tie;
  for (size_t i : order) {
    bool needed = false;
    for (const auto& view : points[i].observations) needed = needed || taken[cell_of(view)] < per_cell;
    if (!needed) continue;
    for (const auto& view : points[i].observations) ++taken[cell_of(view)];
    tie.push_back(i);
  }
  std::sort(tie.begin(), tie.end());
  return tie;
}

PoseMap PosesOf(const std::vector<FrameState*>& registered) {
  PoseMap poses;
  for (const FrameState* frame : registered) poses[frame->frame] = frame->cam_from_world.ToRigid();
  return poses;
}

// How far an adjustment moved the cameras where the points are seen, px:
// the median over the points' views of the distance between the point's
// projections through the cameras before and after.
double MedianShiftAtPointsPx(const PoseMap& before, const CameraModel& camera_before, const PoseMap& after,
                             const CameraModel& camera_after, const std::vector<FeaturePoint>& points) {
  std::vector<double> shifts;
  for (const FeaturePoint& p : points) {
    for (const auto& view : p.observations) {
      const Eigen::Vector3d old_cam = before.at(view.first) * p.position, new_cam = after.at(view.first) * p.position;
      if (old_cam.z() > 0 && new_cam.z() > 0) {
        shifts.push_back((camera_after.Project(new_cam) - camera_before.Project(old_cam)).norm());
      }
    }
  }
  if (shifts.empty()) return 0.0;
  const auto middle = shifts.begin() + static_cast<std::ptrdiff_t>(shifts.size() / 2);
  std::nth_element(shifts.begin(), middle, shifts.end());
  return *middle;
}

}  // namespace

void Reconstructor::TriangulateAndAdjust(const std::vector<FrameState*>& registered, const PointTriangulation& triangulate,
                                         ReconstructionResult* result) {
  PoseMap poses = PosesOf(registered);
  for (int round = 0;; ++round) {
    const CameraModel camera = camera_;
    result->feature_points = triangulate(poses, camera_);
    if (!options_.final_adjustment) return;
    AdjustWithPoints(registered, &result->feature_points, result);
    PoseMap adjusted = PosesOf(registered);
    result->points_shift_px = MedianShiftAtPointsPx(poses, camera, adjusted, camera_, result->feature_points);
    if (!(result->points_shift_px > options_.points_refit_shift_px) || round == options_.max_points_refits) return;
    ++result->points_refits;
    poses = std::move(adjusted);
  }
}

void Reconstructor::AdjustWithPoints(const std::vector<FrameState*>& registered, std::vector<FeaturePoint>* points,
                                     ReconstructionResult* result) {
  if (points->empty()) return;
  // Each kind counts by its precision: the corners' noise per axis from the
  // targets' reprojection after the final adjustment, the points' from
  // their tracks (SIFT keypoints, ~10x noisier).
  std::vector<double> point_rms;
  for (const FeaturePoint& p : *points) point_rms.push_back(p.reprojection_rms_px);
  std::nth_element(point_rms.begin(), point_rms.begin() + static_cast<long>(point_rms.size() / 2), point_rms.end());
  ReconstructionResult tags_only;
  CollectReprojectionStatistics(registered, &tags_only);
  const double corner_sigma = std::max(0.01, tags_only.reprojection_rms_px / std::sqrt(2.0));
  const double point_sigma = std::max(0.1, point_rms[point_rms.size() / 2] / std::sqrt(2.0));
  const std::vector<size_t> tie = TiePoints(*points, options_.tie_points_per_keyframe, camera_);
  std::vector<AdjustedPoint> adjusted(tie.size());
  for (size_t k = 0; k < tie.size(); ++k) {
    adjusted[k].position = (*points)[tie[k]].position;
    adjusted[k].observations = (*points)[tie[k]].observations;
  }
  PointTerms terms;
  terms.points = &adjusted;
  terms.camera = &camera_;
  terms.weight = corner_sigma / point_sigma;
  terms.huber_px = 2 * point_sigma;
  BundleAdjusterOptions options = options_.ba;
  options.square_pixels = square_pixels_;
  // The targets' covariance from this adjustment: the points' rays, which
  // moved the tags, inform their sigma too (the tags-only one is kept if
  // this one cannot be computed).
  options.compute_covariance = true;
  // 8 iterations: the points start at their triangulation, the poses at the
  // targets-only optimum; the 1280x720 box walk, box_small, wall_small and
  // box_photos give clouds within 0.1 um (median; 0.4 um at the 99th
  // percentile) of 40 iterations' in a fifth of the time.
  options.global_iterations = std::min(options.global_iterations, 8);
  const GlobalAdjustmentSummary summary = AdjustGlobally(registered, &tags_, fx_, fy_, options,
                                                         result->intrinsics_refined ? &camera_ : nullptr, &terms);
  result->points_adjusted = static_cast<int>(adjusted.size());
  result->points_adjustment_s = summary.solve_s;
  if (summary.covariance) {
    result->covariance = summary.covariance;
    result->covariance_note = summary.covariance_note;
    if (summary.intrinsics_covariance) result->intrinsics_covariance = summary.intrinsics_covariance;
  }
  result->covariance_s += summary.covariance_s;
  const PoseMap poses = PosesOf(registered);
  // The tie points where the adjustment put them, the others refined on its poses.
  std::vector<bool> in_adjustment(points->size(), false);
  for (size_t k = 0; k < tie.size(); ++k) {
    (*points)[tie[k]].position = adjusted[k].position;
    in_adjustment[tie[k]] = true;
  }
  std::vector<size_t> rest;
  for (size_t i = 0; i < points->size(); ++i) {
    if (!in_adjustment[i]) rest.push_back(i);
  }
  HeldPoseRefinementOptions held;
  held.huber_px = terms.huber_px;
  held.threads = options_.points_threads;
  const auto t0 = std::chrono::steady_clock::now();
  RefinePointsOnHeldPoses(poses, camera_, held, rest, points);
  result->points_adjustment_s += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  // Kept where the adjusted point still reprojects like a point of its kind.
  std::vector<FeaturePoint> kept;
  for (FeaturePoint& p : *points) {
    double sum = 0;
    bool in_front = true;
    for (const auto& [frame, pixel] : p.observations) {
      const Eigen::Vector3d in_cam = poses.at(frame) * p.position;
      in_front = in_front && in_cam.z() > 0;
      sum += (camera_.Project(in_cam) - pixel).squaredNorm();
    }
    const double triangulated_rms_px = p.reprojection_rms_px;
    p.reprojection_rms_px = std::sqrt(sum / static_cast<double>(p.observations.size()));
    if (in_front && p.reprojection_rms_px <= std::max(2.0 * triangulated_rms_px, 1.0)) kept.push_back(std::move(p));
  }
  *points = std::move(kept);
}

void Reconstructor::CollectReprojectionStatistics(const std::vector<FrameState*>& registered,
                                                  ReconstructionResult* result) const {
  // In pixels, through the full camera model.
  double sum_all = 0;
  int n_all = 0;
  std::map<TagId, std::pair<double, int>> per_tag;
  std::map<TagId, int> outliers;
  for (FrameState* frame : registered) {
    const Rigid3d cam_from_world = frame->cam_from_world.ToRigid();
    for (const auto& obs : frame->tags) {
      auto it = tags_.find(obs.id);
      if (it == tags_.end()) continue;
      if (obs.outlier) {
        ++outliers[obs.id];
        continue;
      }
      const TagCorners corners = it->second.CornersInWorld();
      auto& [sum, count] = per_tag[obs.id];
      for (int k = 0; k < 4; ++k) {
        const double err2 = (camera_.Project(cam_from_world * corners[k]) - obs.pixels[k]).squaredNorm();
        sum += err2;
        sum_all += err2;
      }
      ++count;
      n_all += 4;
    }
  }
  for (const auto& [id, tag] : tags_) {
    TargetStats stats;
    stats.known = tag.known;
    if (auto it = per_tag.find(id); it != per_tag.end()) {
      stats.track_length = it->second.second;
      stats.rms_px = std::sqrt(it->second.first / (4.0 * it->second.second));
    }
    if (auto it = outliers.find(id); it != outliers.end()) stats.outlier_views = it->second;
    result->target_stats[id] = stats;
  }
  result->reprojection_rms_px = n_all ? std::sqrt(sum_all / n_all) : 0.0;
  result->observations = n_all;
}

TargetCornerMap Reconstructor::MappedTargetCorners() const {
  TargetCornerMap corners;
  for (const auto& [id, tag] : tags_) corners[id] = tag.CornersInWorld();
  return corners;
}

}  // namespace tagsfm
