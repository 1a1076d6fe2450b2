#include "tagsfm/feature/track_refinement.h"

#include <algorithm>
#include <cmath>

#include <Eigen/Geometry>
#include <Eigen/LU>

namespace tagsfm {

namespace {

// d pixel / d (plane coordinates) at `point`, by central differences of the
// full (distorted) projection.
Eigen::Matrix2d PlaneToPixel(const Eigen::Vector3d& point, const Eigen::Matrix<double, 3, 2>& basis, const Rigid3d& cam_from_world,
                             const CameraModel& camera, double step) {
  Eigen::Matrix2d j;
  for (int k = 0; k < 2; ++k) {
    const Eigen::Vector3d d = step * basis.col(k);
    j.col(k) = (camera.Project(cam_from_world * (point + d)) - camera.Project(cam_from_world * (point - d))) / (2 * step);
  }
  return j;
}

// RefinePatch with the reference patch on pyramid level `reference_level`
// and the target on `target_level` (pixel i of level l is pixel 2^l i of
// the full image); `start` and the fit are in full-image pixels.
std::optional<PatchFit> RefineOnLevels(const cv::Mat& reference, const Eigen::Vector2d& reference_pixel, const cv::Mat& target,
                                       PatchWarp start, const PatchRefinementOptions& options, int reference_level,
                                       int target_level, std::optional<PatchLine> line = std::nullopt) {
  const double reference_size = std::ldexp(1.0, reference_level), target_size = std::ldexp(1.0, target_level);
  start.centre /= target_size;
  start.affine *= reference_size / target_size;
  if (line) line->across_sigma_px /= target_size;
  std::optional<PatchFit> fit = RefinePatch(reference, reference_pixel / reference_size, target, start, options, line);
  if (fit) {
    fit->warp.centre *= target_size;
    fit->warp.affine *= target_size / reference_size;
    fit->sigma_px *= target_size;
  }
  return fit;
}

// The levels of the reference and the target image that see the surface at
// about one scale: where the target sees it 1.4x larger or more (affine's
// scale), its patch comes from a coarser level, and the reference's where
// it is 1.4x smaller, so neither patch is sampled sparser than its pixels.
struct FitLevels {
  int reference, target;
};

FitLevels BalancedLevels(const Eigen::Matrix2d& affine, const PatchRefinementOptions& options) {
  if (!options.balance_scale) return {0, 0};
  const double steps = std::round(0.5 * std::log2(std::max(1e-6, std::abs(affine.determinant()))));
  const int k = static_cast<int>(std::clamp(steps, -double(options.max_level), double(options.max_level)));
  return {std::max(0, -k), std::max(0, k)};
}

// The reference pixel's ray: the reference camera's centre, the unit
// direction, and the first point's depth along it.
struct ReferenceRay {
  Eigen::Vector3d origin, direction;
  double depth;
};

// The ray's epipolar line in `target` where the point at the ray's depth
// projects: that projection and the line's unit direction there. nullopt
// when the depth barely moves the projection (the view tells no depth).
std::optional<PatchLine> EpipolarLine(const ReferenceRay& ray, const Rigid3d& target, const CameraModel& camera,
                                      Eigen::Vector2d* centre) {
  const double step = 1e-3 * ray.depth;
  const Eigen::Vector3d near = target * (ray.origin + (ray.depth - step) * ray.direction);
  const Eigen::Vector3d far = target * (ray.origin + (ray.depth + step) * ray.direction);
  if (!(ray.depth > 0 && near.z() > 0 && far.z() > 0)) return std::nullopt;
  const Eigen::Vector2d slope = camera.Project(far) - camera.Project(near);
  if (!(slope.norm() > 1e-6)) return std::nullopt;
  *centre = camera.Project(target * (ray.origin + ray.depth * ray.direction));
  return PatchLine{slope.normalized(), 0.0};
}

// One view's fit: free from `start`, and when that is refused and
// `epipolar_sigma_px` > 0, again with the centre on the reference ray's
// epipolar line. The free fit's distance across the line goes in `report`.
std::optional<PatchFit> FitView(const cv::Mat& reference_image, const Eigen::Vector2d& reference_pixel, const cv::Mat& target,
                                const PatchWarp& start, const FitLevels& levels, const ReferenceRay& ray,
                                const Rigid3d& target_pose, const CameraModel& camera,
                                const PatchRefinementOptions& options, double epipolar_sigma_px,
                                TrackRefinementReport* report) {
  std::optional<PatchFit> fit =
      RefineOnLevels(reference_image, reference_pixel, target, start, options, levels.reference, levels.target);
  Eigen::Vector2d on_line;
  std::optional<PatchLine> line = EpipolarLine(ray, target_pose, camera, &on_line);
  if (!line) return fit;
  if (fit) {
    const Eigen::Vector2d across(-line->direction.y(), line->direction.x());
    if (report != nullptr) report->across_epipolar_px.push_back(across.dot(fit->warp.centre - on_line));
    return fit;
  }
  if (!(epipolar_sigma_px > 0)) return fit;
  line->across_sigma_px = epipolar_sigma_px;
  PatchWarp line_start = start;
  line_start.centre = on_line;
  fit = RefineOnLevels(reference_image, reference_pixel, target, line_start, options, levels.reference, levels.target, line);
  if (fit && report != nullptr) ++report->line_fits;
  return fit;
}

}  // namespace

Eigen::Matrix2d PredictPatchAffine(const Eigen::Vector3d& point, const Eigen::Vector3d& normal, const Rigid3d& reference,
                                   const Rigid3d& target, const CameraModel& camera) {
  Eigen::Matrix<double, 3, 2> basis;
  basis.col(0) = normal.unitOrthogonal();
  basis.col(1) = normal.cross(basis.col(0)).normalized();
  // A millimetre-scale step at metre depths: far above rounding, far below
  // the curvature of the projection.
  const double step = 1e-3 * std::max(1e-3, (point - reference.Center()).norm());
  const Eigen::Matrix2d from_ref = PlaneToPixel(point, basis, reference, camera, step);
  const Eigen::Matrix2d to_target = PlaneToPixel(point, basis, target, camera, step);
  if (std::abs(from_ref.determinant()) < 1e-12) return Eigen::Matrix2d::Identity();
  return to_target * from_ref.inverse();
}

namespace {

// The surface normals a refused fit starts from again, in order: the plane
// facing the cameras (`mean_direction`) tilted by k * options.tilt_step_deg,
// k = 1 .. tilt_retries, each way, about the normal of the plane of the
// reference's and the view's rays (unit, point to camera). A tilted plane
// that either camera would see at more than 85 degrees is left out: its
// warp squeezes the patch to a line.
std::vector<Eigen::Vector3d> TiltedNormals(const Eigen::Vector3d& mean_direction, const Eigen::Vector3d& reference_direction,
                                           const Eigen::Vector3d& view_direction, const PatchRefinementOptions& options) {
  std::vector<Eigen::Vector3d> normals;
  const Eigen::Vector3d axis = reference_direction.cross(view_direction);
  if (!(axis.norm() > 1e-9)) return normals;  // the same ray: no plane to tilt in
  const double min_cos = std::cos(85.0 * M_PI / 180.0);
  for (int k = 1; k <= options.tilt_retries; ++k) {
    for (const double sign : {1.0, -1.0}) {
      const Eigen::Vector3d normal =
          Eigen::AngleAxisd(sign * k * options.tilt_step_deg * M_PI / 180.0, axis.normalized()) * mean_direction;
      if (normal.dot(reference_direction) > min_cos && normal.dot(view_direction) > min_cos) normals.push_back(normal);
    }
  }
  return normals;
}

struct TrackView {
  TrackObservation observation;
  Rigid3d pose;
  Eigen::Vector3d direction;  // from the point to the camera, unit
};

// The track's views fitted to views[reference]; empty when too few remain.
FeatureTrack RefineAgainst(const std::vector<TrackView>& views, size_t reference_index, const FeatureTrack& track,
                           const FeaturePoint& point, const Eigen::Vector3d& mean_direction,
                           const KeyframeImageLookup& image_of, const CameraModel& camera,
                           const PatchRefinementOptions& options, double unrefined_sigma_px, double epipolar_sigma_px,
                           TrackRefinementReport* report) {
  FeatureTrack out;
  out.id = track.id;
  const TrackView& reference = views[reference_index];
  const Eigen::Vector2d reference_pixel = reference.observation.pixel;
  // Where the point projects in the reference, against its SIFT pixel: the
  // prediction in each other view is offset by the same patch shift.
  const Eigen::Vector2d reference_offset = reference_pixel - camera.Project(reference.pose * point.position);
  ReferenceRay ray;
  ray.origin = reference.pose.Center();
  ray.direction = (reference.pose.rotation.conjugate() * camera.PixelToNormalized(reference_pixel).homogeneous()).normalized();
  ray.depth = (point.position - ray.origin).dot(ray.direction);
  int unrefined = 0;
  for (size_t i = 0; i < views.size(); ++i) {
    const TrackView& v = views[i];
    if (i == reference_index) {
      out.observations.push_back(v.observation);
      continue;
    }
    // The fit from the warp of a plane with this normal through the point.
    const auto fit_from = [&](const Eigen::Vector3d& normal) -> std::optional<PatchFit> {
      PatchWarp start;
      start.affine = PredictPatchAffine(point.position, normal, reference.pose, v.pose, camera);
      start.centre = camera.Project(v.pose * point.position) + start.affine * reference_offset;
      const FitLevels levels = BalancedLevels(start.affine, options);
      const cv::Mat* reference_image = image_of(reference.observation.frame, levels.reference);
      const cv::Mat* target = image_of(v.observation.frame, levels.target);
      if (reference_image == nullptr || target == nullptr) return std::nullopt;
      return FitView(*reference_image, reference_pixel, *target, start, levels, ray, v.pose, camera, options,
                     epipolar_sigma_px, report);
    };
    std::optional<PatchFit> fit = fit_from(mean_direction);
    if (!fit) {
      for (const Eigen::Vector3d& normal : TiltedNormals(mean_direction, reference.direction, v.direction, options)) {
        fit = fit_from(normal);
        if (!fit) continue;
        if (report != nullptr) ++report->tilted_fits;
        break;
      }
    }
    if (!fit) {
      if (unrefined_sigma_px <= 0) continue;
      TrackObservation kept = v.observation;
      kept.sigma_px = std::max(kept.sigma_px, unrefined_sigma_px);
      out.observations.push_back(kept);
      ++unrefined;
      continue;
    }
    TrackObservation moved = v.observation;
    moved.pixel = fit->warp.centre;
    moved.sigma_px = fit->sigma_px;
    out.observations.push_back(moved);
  }
  const int refined = static_cast<int>(out.observations.size()) - unrefined;  // the reference counts
  if (out.observations.size() < 2 || (refined < 2 && out.observations.size() < 3)) out.observations.clear();
  std::sort(out.observations.begin(), out.observations.end(),
            [](const TrackObservation& a, const TrackObservation& b) { return a.frame < b.frame; });
  return out;
}

}  // namespace

FeatureTrack RefineTrackViews(const FeatureTrack& track, const FeaturePoint& point, const PoseMap& cam_from_world,
                              const KeyframeImageLookup& image_of, const CameraModel& camera,
                              const PatchRefinementOptions& options, double unrefined_sigma_px, double epipolar_sigma_px,
                              TrackRefinementReport* report) {
  std::vector<TrackView> views;
  Eigen::Vector3d mean_direction = Eigen::Vector3d::Zero();
  for (const auto& observation : point.observations) {
    const FrameId frame = observation.first;  // not a structured binding: clang 14 cannot capture one
    const auto pose = cam_from_world.find(frame);
    const cv::Mat* image = image_of(frame, 0);
    if (pose == cam_from_world.end() || image == nullptr || image->empty()) continue;
    const auto o = std::find_if(track.observations.begin(), track.observations.end(),
                                [&](const TrackObservation& t) { return t.frame == frame; });
    if (o == track.observations.end()) continue;
    const Eigen::Vector3d direction = (pose->second.Center() - point.position).normalized();
    views.push_back({*o, pose->second, direction});
    mean_direction += direction;
  }
  FeatureTrack out;
  out.id = track.id;
  if (views.size() < 2) return out;
  mean_direction.normalize();
  // References nearest the mean viewing direction first. When one leaves
  // too few views, its own patch was the odd one out (a wrong match, an
  // occlusion, a blurred frame) and the next is tried; a track kept that
  // way needs three views, as a track without fits does: two that fit only
  // each other were measured to be 1.3x less accurate than their sigma
  // says (docs/features.md).
  std::vector<size_t> order(views.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) {
    return views[a].direction.dot(mean_direction) > views[b].direction.dot(mean_direction);
  });
  const size_t attempts = std::min(order.size(), static_cast<size_t>(options.reference_attempts));
  for (size_t k = 0; k < attempts; ++k) {
    TrackRefinementReport attempt;
    out = RefineAgainst(views, order[k], track, point, mean_direction, image_of, camera, options, unrefined_sigma_px,
                        epipolar_sigma_px, report != nullptr ? &attempt : nullptr);
    const bool kept = out.observations.size() >= (k == 0 ? 2u : 3u);
    // A discarded attempt's free fits still measure the lines' error; its
    // line and tilted fits are not in the track, so they are not counted.
    if (report != nullptr) {
      report->across_epipolar_px.insert(report->across_epipolar_px.end(), attempt.across_epipolar_px.begin(),
                                        attempt.across_epipolar_px.end());
      if (kept) {
        report->line_fits += attempt.line_fits;
        report->tilted_fits += attempt.tilted_fits;
      }
    }
    if (kept) break;
    out.observations.clear();
  }
  return out;
}

}  // namespace tagsfm
