#include "tagsfm/feature/track_refinement.h"

#include <algorithm>

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

FeatureTrack RefineTrackViews(const FeatureTrack& track, const FeaturePoint& point, const PoseMap& cam_from_world,
                              const KeyframeImageLookup& image_of, const CameraModel& camera,
                              const PatchRefinementOptions& options, double unrefined_sigma_px) {
  struct View {
    TrackObservation observation;
    Rigid3d pose;
    const cv::Mat* image;
    Eigen::Vector3d direction;  // from the point to the camera, unit
  };
  std::vector<View> views;
  Eigen::Vector3d mean_direction = Eigen::Vector3d::Zero();
  for (const auto& observation : point.observations) {
    const FrameId frame = observation.first;  // not a structured binding: clang 14 cannot capture one
    const auto pose = cam_from_world.find(frame);
    const cv::Mat* image = image_of(frame);
    if (pose == cam_from_world.end() || image == nullptr || image->empty()) continue;
    const auto o = std::find_if(track.observations.begin(), track.observations.end(),
                                [&](const TrackObservation& t) { return t.frame == frame; });
    if (o == track.observations.end()) continue;
    const Eigen::Vector3d direction = (pose->second.Center() - point.position).normalized();
    views.push_back({*o, pose->second, image, direction});
    mean_direction += direction;
  }
  FeatureTrack out;
  out.id = track.id;
  if (views.size() < 2) return out;
  mean_direction.normalize();
  const auto reference = std::max_element(views.begin(), views.end(), [&](const View& a, const View& b) {
    return a.direction.dot(mean_direction) < b.direction.dot(mean_direction);
  });
  const Eigen::Vector2d reference_pixel = reference->observation.pixel;
  // Where the point projects in the reference, against its SIFT pixel: the
  // prediction in each other view is offset by the same patch shift.
  const Eigen::Vector2d reference_offset = reference_pixel - camera.Project(reference->pose * point.position);
  int unrefined = 0;
  for (const View& v : views) {
    if (&v == &*reference) {
      out.observations.push_back(v.observation);
      continue;
    }
    PatchWarp start;
    start.affine = PredictPatchAffine(point.position, mean_direction, reference->pose, v.pose, camera);
    start.centre = camera.Project(v.pose * point.position) + start.affine * reference_offset;
    const std::optional<PatchFit> fit = RefinePatch(*reference->image, reference_pixel, *v.image, start, options);
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

}  // namespace tagsfm
