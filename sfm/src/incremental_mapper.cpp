#include "tagsfm/sfm/incremental_mapper.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>
#include <memory>
#include <set>
#include <string>

#include <sstream>

namespace tagsfm::sfm {

Status IncrementalMapperOptions::Check() const {
  if (!(ratio > 0 && ratio <= 1)) return MakeError("sfm.ratio must be in (0, 1]");
  if (match_window < 0) return MakeError("sfm.match_window must be >= 0 (0: every pair)");
  if (!(max_error_px > 0)) return MakeError("sfm.max_error_px must be > 0");
  if (!(abs_pose_max_error_px > 0)) return MakeError("sfm.abs_pose_max_error_px must be > 0");
  if (abs_pose_min_inliers < 4) return MakeError("sfm.abs_pose_min_inliers must be >= 4");
  if (init_min_inliers < 15) return MakeError("sfm.init_min_inliers must be >= 15");
  if (!(init_min_angle_deg > 0)) return MakeError("sfm.init_min_angle_deg must be > 0");
  if (!(min_angle_deg > 0)) return MakeError("sfm.min_angle_deg must be > 0");
  if (local_ba_images < 2) return MakeError("sfm.local_ba_images must be >= 2");
  if (!(global_ba_growth > 1)) return MakeError("sfm.global_ba_growth must be > 1");
  if (!(huber_px > 0)) return MakeError("sfm.huber_px must be > 0");
  if (max_registration_trials < 1) return MakeError("sfm.max_registration_trials must be >= 1");
  return Status::Ok();
}

PointFit FitOfPoint(const SfmModel& model, PointIdx point, const CameraModel& camera) {
  const SfmPoint& p = model.points[point];
  PointFit fit;
  std::vector<View> views;
  double sum_sq = 0;
  for (const Observation& obs : p.track) {
    const SfmImage& image = model.images[obs.image];
    const Eigen::Vector3d in_cam = image.cam_from_world * p.xyz;
    sum_sq += (camera.Project(in_cam) - image.pixels[obs.feature]).squaredNorm();
    views.push_back({image.cam_from_world, image.normalized[obs.feature]});
  }
  if (!p.track.empty()) fit.rms_px = std::sqrt(sum_sq / static_cast<double>(p.track.size()));
  fit.max_angle_deg = MaxTriangulationAngleDeg(views, p.xyz);
  return fit;
}

namespace {

double Seconds(std::chrono::steady_clock::time_point since) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - since).count();
}

struct VerifiedPair {
  ImageIdx a = -1, b = -1;
  std::vector<FeatureMatch> inliers;
  RelativePose pose;
};

class Mapper {
 public:
  Mapper(const std::vector<KeyframeFeatures>& views, const CameraModel& camera, const IncrementalMapperOptions& options)
      : views_(views), options_(options), focal_(0.5 * (camera.fx + camera.fy)) {
    corr_.resize(views.size());
    for (const KeyframeFeatures& v : views) {
      SfmImage image;
      image.frame = v.frame;
      image.pixels = v.pixels;
      image.normalized = camera.PixelsToNormalized(v.pixels);
      image.point_of_feature.assign(v.pixels.size(), -1);
      image.reason = "not registered: too few 2D-3D correspondences with the model";
      model_.images.push_back(std::move(image));
    }
    for (size_t i = 0; i < views.size(); ++i) corr_[i].resize(views[i].pixels.size());
    trials_.assign(views.size(), 0);
    bundle_.fx = camera.fx;
    bundle_.fy = camera.fy;
    bundle_.huber_px = options.huber_px;
  }

  void MatchAll();
  Status Initialize();
  void RegisterRest();
  void Finish();
  MapperResult Take() { return {std::move(model_), stats_}; }

 private:
  double Limit() const { return options_.max_error_px / focal_; }
  View ViewOf(Observation obs) const {
    return {model_.images[obs.image].cam_from_world, model_.images[obs.image].normalized[obs.feature]};
  }
  bool Register(ImageIdx image);
  int TriangulateImage(ImageIdx image);
  void CompleteTracks();
  void FilterPoints();
  void AdjustLocal(ImageIdx image);
  void AdjustGlobal();
  int VisiblePoints(ImageIdx image) const;

  const std::vector<KeyframeFeatures>& views_;
  const IncrementalMapperOptions& options_;
  const double focal_;
  SfmModel model_;
  MapperStats stats_;
  BundleOptions bundle_;
  std::vector<VerifiedPair> pairs_;
  std::vector<std::vector<std::vector<Observation>>> corr_;  // image, feature -> verified matches
  std::vector<int> trials_;
  int registered_at_last_global_ = 0;
};

void Mapper::MatchAll() {
  const auto start = std::chrono::steady_clock::now();
  // FLANN's k-d trees search floats: the views' descriptors as floats while
  // matching.
  std::vector<cv::Mat> descriptors;
  std::vector<std::unique_ptr<DescriptorIndex>> indexes;
  for (const KeyframeFeatures& v : views_) descriptors.push_back(DescriptorsAsFloat(v.descriptors));
  for (const cv::Mat& d : descriptors) indexes.push_back(std::make_unique<DescriptorIndex>(d));
  RelativePoseOptions rel;
  rel.max_error_px = options_.max_error_px;
  rel.focal_px = focal_;
  const int n = static_cast<int>(views_.size());
  for (int a = 0; a < n; ++a) {
    for (int b = a + 1; b < n; ++b) {
      if (options_.match_window > 0 && b - a > options_.match_window) break;
      ++stats_.pairs_matched;
      const std::vector<FeatureMatch> matches =
          MatchMutual(descriptors[static_cast<size_t>(a)], *indexes[a], descriptors[static_cast<size_t>(b)], *indexes[b], options_.ratio);
      if (static_cast<int>(matches.size()) < rel.min_inliers) continue;
      std::vector<Eigen::Vector2d> na, nb;
      for (const FeatureMatch& m : matches) {
        na.push_back(model_.images[a].normalized[m.a]);
        nb.push_back(model_.images[b].normalized[m.b]);
      }
      Result<RelativePose> pose = EstimateRelativePose(na, nb, rel);
      if (!pose) continue;
      VerifiedPair pair{a, b, {}, *pose};
      for (int i : pose->inliers) {
        const FeatureMatch& m = matches[i];
        pair.inliers.push_back(m);
        corr_[a][m.a].push_back({b, m.b});
        corr_[b][m.b].push_back({a, m.a});
      }
      pairs_.push_back(std::move(pair));
      ++stats_.pairs_verified;
    }
  }
  stats_.matching_s = Seconds(start);
}

Status Mapper::Initialize() {
  // COLMAP's order: most inliers first, among pairs wide enough to
  // triangulate; halve both demands (as its mapper does on failure) until one qualifies.
  std::vector<const VerifiedPair*> order;
  for (const VerifiedPair& p : pairs_) order.push_back(&p);
  std::sort(order.begin(), order.end(), [](auto* x, auto* y) { return x->inliers.size() > y->inliers.size(); });
  double min_angle = options_.init_min_angle_deg;
  int min_inliers = options_.init_min_inliers;
  const VerifiedPair* chosen = nullptr;
  for (int relax = 0; relax < 4 && !chosen; ++relax, min_angle /= 2, min_inliers = std::max(15, min_inliers / 2)) {
    for (const VerifiedPair* p : order) {
      if (static_cast<int>(p->inliers.size()) >= min_inliers && p->pose.median_angle_deg >= min_angle) {
        chosen = p;
        break;
      }
    }
  }
  if (!chosen) {
    std::string best = "none";
    if (!order.empty()) {
      std::ostringstream text;
      text.precision(3);
      text << order[0]->inliers.size() << " inliers at " << order[0]->pose.median_angle_deg << " deg";
      best = text.str();
    }
    return MakeError("no initial pair: " + std::to_string(pairs_.size()) + " of " + std::to_string(stats_.pairs_matched) +
                     " view pairs verified by the essential matrix (most inliers: " + best +
                     "); too few matches, no texture or a camera that only rotates");
  }
  stats_.init_a = chosen->a;
  stats_.init_b = chosen->b;
  stats_.init_inliers = static_cast<int>(chosen->inliers.size());
  stats_.init_angle_deg = chosen->pose.median_angle_deg;
  SfmImage& a = model_.images[chosen->a];
  SfmImage& b = model_.images[chosen->b];
  a.registered = b.registered = true;
  a.cam_from_world = Rigid3d();
  b.cam_from_world = chosen->pose.cam_b_from_cam_a;
  model_.gauge_origin = chosen->a;
  model_.gauge_scale = chosen->b;
  TriangulateImage(chosen->b);
  AdjustGlobal();
  if (model_.LivePoints() < options_.abs_pose_min_inliers) {
    return MakeError("initial pair (frames " + std::to_string(a.frame) + ", " + std::to_string(b.frame) + "): only " +
                     std::to_string(model_.LivePoints()) + " points survive triangulation and adjustment");
  }
  registered_at_last_global_ = 2;
  return Status::Ok();
}

int Mapper::VisiblePoints(ImageIdx image) const {
  std::set<PointIdx> seen;
  for (const auto& matches : corr_[image]) {
    for (const Observation& m : matches) {
      const PointIdx p = model_.images[m.image].point_of_feature[m.feature];
      if (p >= 0) seen.insert(p);
    }
  }
  return static_cast<int>(seen.size());
}

bool Mapper::Register(ImageIdx image) {
  SfmImage& target = model_.images[image];
  std::vector<Eigen::Vector3d> xyz;
  std::vector<Eigen::Vector2d> normalized;
  std::vector<std::pair<int, PointIdx>> feature_point;
  std::set<PointIdx> used;
  for (int f = 0; f < static_cast<int>(corr_[image].size()); ++f) {
    for (const Observation& m : corr_[image][f]) {
      const PointIdx p = model_.images[m.image].point_of_feature[m.feature];
      if (p < 0 || used.count(p)) continue;
      used.insert(p);
      xyz.push_back(model_.points[p].xyz);
      normalized.push_back(target.normalized[f]);
      feature_point.push_back({f, p});
      break;
    }
  }
  AbsolutePoseOptions abs;
  abs.max_error_px = options_.abs_pose_max_error_px;
  abs.focal_px = focal_;
  abs.min_inliers = options_.abs_pose_min_inliers;
  Result<AbsolutePose> pose = EstimateAbsolutePose(xyz, normalized, abs);
  if (!pose) {
    target.reason = "not registered: " + pose.error().message;
    return false;
  }
  target.registered = true;
  target.reason.clear();
  target.cam_from_world = pose->cam_from_world;
  for (int i : pose->inliers) {
    const auto [f, p] = feature_point[i];
    if (ReprojectionError({target.cam_from_world, target.normalized[f]}, model_.points[p].xyz) > Limit()) continue;
    const auto& track = model_.points[p].track;
    if (std::none_of(track.begin(), track.end(), [&](const Observation& o) { return o.image == image; })) {
      model_.AddObservation(p, {image, f});
    }
  }
  return true;
}

// New points from the image's features that match features of registered
// images without a point; features whose match has a point join it when it
// reprojects within the limit (COLMAP's IncrementalTriangulator, without
// its transitive correspondences and track merging).
int Mapper::TriangulateImage(ImageIdx image) {
  int created = 0;
  const SfmImage& target = model_.images[image];
  for (int f = 0; f < static_cast<int>(corr_[image].size()); ++f) {
    if (model_.images[image].point_of_feature[f] >= 0) continue;
    std::vector<Observation> track = {{image, f}};
    std::set<ImageIdx> in_track = {image};
    PointIdx existing = -1;
    for (const Observation& m : corr_[image][f]) {
      const SfmImage& other = model_.images[m.image];
      if (!other.registered || in_track.count(m.image)) continue;
      const PointIdx p = other.point_of_feature[m.feature];
      if (p >= 0) {
        if (existing < 0) existing = p;
        continue;
      }
      track.push_back(m);
      in_track.insert(m.image);
    }
    if (existing >= 0) {
      const auto& t = model_.points[existing].track;
      const bool seen = std::any_of(t.begin(), t.end(), [&](const Observation& o) { return o.image == image; });
      if (!seen && ReprojectionError({target.cam_from_world, target.normalized[f]}, model_.points[existing].xyz) <= Limit()) {
        model_.AddObservation(existing, {image, f});
        continue;
      }
    }
    if (track.size() < 2) continue;
    std::vector<View> views;
    for (const Observation& o : track) views.push_back(ViewOf(o));
    const auto xyz = TriangulateViews(views);
    if (!xyz) continue;
    // Drop views that disagree, then ask for the angle on what is left.
    std::vector<Observation> kept;
    std::vector<View> kept_views;
    for (size_t k = 0; k < track.size(); ++k) {
      if (ReprojectionError(views[k], *xyz) <= Limit()) {
        kept.push_back(track[k]);
        kept_views.push_back(views[k]);
      }
    }
    if (kept.size() < 2 || kept.front().image != image) continue;
    if (MaxTriangulationAngleDeg(kept_views, *xyz) < options_.min_angle_deg) continue;
    model_.AddPoint(*xyz, views_[image].rgb[f], std::move(kept));
    ++created;
  }
  return created;
}

// Adds views of a point through verified matches where it reprojects within
// the limit (COLMAP's CompleteTracks).
void Mapper::CompleteTracks() {
  for (PointIdx p = 0; p < static_cast<PointIdx>(model_.points.size()); ++p) {
    if (model_.points[p].deleted) continue;
    const std::vector<Observation> snapshot = model_.points[p].track;
    std::set<ImageIdx> in_track;
    for (const Observation& o : snapshot) in_track.insert(o.image);
    for (const Observation& o : snapshot) {
      for (const Observation& m : corr_[o.image][o.feature]) {
        const SfmImage& other = model_.images[m.image];
        if (!other.registered || in_track.count(m.image) || other.point_of_feature[m.feature] >= 0) continue;
        if (ReprojectionError(ViewOf(m), model_.points[p].xyz) > Limit()) continue;
        model_.AddObservation(p, m);
        in_track.insert(m.image);
      }
    }
  }
}

void Mapper::FilterPoints() {
  for (PointIdx p = 0; p < static_cast<PointIdx>(model_.points.size()); ++p) {
    SfmPoint& point = model_.points[p];
    if (point.deleted) continue;
    for (size_t k = point.track.size(); k-- > 0;) {
      if (ReprojectionError(ViewOf(point.track[k]), point.xyz) > Limit()) model_.RemoveObservation(p, k);
    }
    std::vector<View> views;
    for (const Observation& o : point.track) views.push_back(ViewOf(o));
    if (point.track.size() < 2 || MaxTriangulationAngleDeg(views, point.xyz) < options_.min_angle_deg) {
      model_.DeletePoint(p);
    }
  }
}

// The new image and the registered images sharing most points with it.
void Mapper::AdjustLocal(ImageIdx image) {
  std::map<ImageIdx, int> shared;
  for (PointIdx p : model_.images[image].point_of_feature) {
    if (p < 0) continue;
    for (const Observation& o : model_.points[p].track) {
      if (o.image != image) ++shared[o.image];
    }
  }
  std::vector<std::pair<int, ImageIdx>> order;
  for (const auto& [i, n] : shared) order.push_back({n, i});
  std::sort(order.rbegin(), order.rend());
  std::vector<ImageIdx> local = {image};
  for (size_t k = 0; k < order.size() && static_cast<int>(local.size()) < options_.local_ba_images; ++k) {
    local.push_back(order[k].second);
  }
  AdjustBundle(&model_, local, bundle_);
  ++stats_.local_adjustments;
  FilterPoints();
}

void Mapper::AdjustGlobal() {
  stats_.final_adjustment_usable = AdjustBundle(&model_, {}, bundle_).usable;
  ++stats_.global_adjustments;
  FilterPoints();
  registered_at_last_global_ = model_.RegisteredImages();
}

void Mapper::RegisterRest() {
  const auto start = std::chrono::steady_clock::now();
  while (true) {
    ImageIdx next = -1;
    int best = 0;
    for (ImageIdx i = 0; i < static_cast<ImageIdx>(model_.images.size()); ++i) {
      if (model_.images[i].registered || trials_[i] >= options_.max_registration_trials) continue;
      const int visible = VisiblePoints(i);
      if (visible > best) {
        best = visible;
        next = i;
      }
    }
    if (next < 0 || best < options_.abs_pose_min_inliers) break;
    ++trials_[next];
    if (!Register(next)) continue;
    TriangulateImage(next);
    if (model_.RegisteredImages() >= options_.global_ba_growth * registered_at_last_global_) {
      AdjustGlobal();
      CompleteTracks();
    } else {
      AdjustLocal(next);
    }
  }
  stats_.mapping_s = Seconds(start);
}

void Mapper::Finish() {
  const auto start = std::chrono::steady_clock::now();
  AdjustGlobal();
  // Retriangulation: features that failed while fewer views were registered.
  for (ImageIdx i = 0; i < static_cast<ImageIdx>(model_.images.size()); ++i) {
    if (model_.images[i].registered) TriangulateImage(i);
  }
  CompleteTracks();
  AdjustGlobal();
  stats_.mapping_s += Seconds(start);
}

}  // namespace

Result<MapperResult> ReconstructIncremental(const std::vector<KeyframeFeatures>& views, const CameraModel& camera,
                                            const IncrementalMapperOptions& options) {
  if (Status s = options.Check(); !s) return s.error();
  if (Status s = camera.Check(); !s) return s.error();
  if (views.size() < 2) return MakeError("SfM needs at least 2 views (got " + std::to_string(views.size()) + ")");
  for (const KeyframeFeatures& v : views) {
    if (Status s = v.Check(); !s) return s.error();
  }
  Mapper mapper(views, camera, options);
  mapper.MatchAll();
  if (Status s = mapper.Initialize(); !s) return s.error();
  mapper.RegisterRest();
  mapper.Finish();
  return mapper.Take();
}

}  // namespace tagsfm::sfm
