// Reconstructor::Finish: the map completed from what is still waiting, the
// frames registered late, the adjustments, the scale and the statistics.

#include "tagsfm/recon/reconstructor.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "tagsfm/recon/corner_weights.h"
#include "tagsfm/recon/scale_bars.h"
#include "tagsfm/recon/tag_geometry.h"
#include "tagsfm/recon/tag_initializer.h"

namespace tagsfm {

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
