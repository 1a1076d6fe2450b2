#include "tagsfm/recon/reconstructor.h"

#include <algorithm>
#include <cmath>

#include "tagsfm/recon/corner_weights.h"
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

}  // namespace tagsfm
