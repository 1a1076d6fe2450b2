#include "tagsfm/feature/track_triangulation.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>

#include <Eigen/Eigenvalues>

#include "parallel_for.h"

namespace tagsfm {

Status TrackTriangulationOptions::Check() const {
  if (min_views < 2) return MakeError("triangulation.min_views must be >= 2");
  if (!(min_angle_deg > 0 && min_angle_deg < 90)) return MakeError("triangulation.min_angle_deg must be in (0, 90)");
  if (!(max_view_error_px > 0)) return MakeError("triangulation.max_view_error_px must be > 0");
  if (!(max_reprojection_rms_px > 0)) return MakeError("triangulation.max_reprojection_rms_px must be > 0");
  if (!(feature_sigma_px > 0)) return MakeError("triangulation.feature_sigma_px must be > 0");
  if (!(max_relative_sigma > 0)) return MakeError("triangulation.max_relative_sigma must be > 0");
  if (!(covariance_floor_px >= 0)) return MakeError("triangulation.covariance_floor_px must be >= 0");
  if (max_iterations < 1) return MakeError("triangulation.max_iterations must be >= 1");
  return Status::Ok();
}

TrackTriangulationStats& TrackTriangulationStats::operator+=(const TrackTriangulationStats& other) {
  tracks += other.tracks;
  points += other.points;
  too_few_views += other.too_few_views;
  no_linear_point += other.no_linear_point;
  reprojection += other.reprojection;
  narrow_angle += other.narrow_angle;
  predicted_sigma += other.predicted_sigma;
  return *this;
}

namespace {

enum class Outcome { kPoint, kTooFewViews, kNoLinearPoint, kReprojection, kNarrowAngle, kPredictedSigma };

void Count(Outcome outcome, TrackTriangulationStats* stats) {
  ++stats->tracks;
  switch (outcome) {
    case Outcome::kPoint: ++stats->points; break;
    case Outcome::kTooFewViews: ++stats->too_few_views; break;
    case Outcome::kNoLinearPoint: ++stats->no_linear_point; break;
    case Outcome::kReprojection: ++stats->reprojection; break;
    case Outcome::kNarrowAngle: ++stats->narrow_angle; break;
    case Outcome::kPredictedSigma: ++stats->predicted_sigma; break;
  }
}

struct View {
  FeatureRay ray;
  TrackObservation observation;
};

// Reprojection error of each view (infinity behind the camera).
std::vector<double> ViewErrors(const std::vector<View>& views, const Eigen::Vector3d& x, const CameraModel& camera) {
  std::vector<double> errors;
  errors.reserve(views.size());
  for (const View& v : views) {
    const Eigen::Vector3d xc = v.ray.cam_from_world * x;
    errors.push_back(xc.z() > 0 ? (camera.Project(xc) - v.observation.pixel).norm() : std::numeric_limits<double>::infinity());
  }
  return errors;
}

std::vector<FeatureRay> RaysOf(const std::vector<View>& views) {
  std::vector<FeatureRay> rays;
  rays.reserve(views.size());
  for (const View& v : views) rays.push_back(v.ray);
  return rays;
}

double WidestAngleDeg(const std::vector<View>& views, const Eigen::Vector3d& x) {
  double widest_cos = 1.0;
  for (size_t i = 0; i < views.size(); ++i) {
    const Eigen::Vector3d a = (x - views[i].ray.cam_from_world.Center()).normalized();
    for (size_t k = i + 1; k < views.size(); ++k) {
      widest_cos = std::min(widest_cos, a.dot((x - views[k].ray.cam_from_world.Center()).normalized()));
    }
  }
  return std::acos(std::clamp(widest_cos, -1.0, 1.0)) * 180.0 / M_PI;
}

// The track's point, or why there is none.
std::optional<FeaturePoint> TriangulateOne(const FeatureTrack& track, std::vector<View> views, const CameraModel& camera,
                                           const TrackTriangulationOptions& options, Outcome* outcome) {
  Eigen::Vector3d x;
  std::vector<double> errors;
  while (true) {
    *outcome = Outcome::kTooFewViews;
    if (static_cast<int>(views.size()) < options.min_views) return std::nullopt;
    const std::vector<FeatureRay> rays = RaysOf(views);
    const std::optional<Eigen::Vector3d> start = TriangulateLinear(rays);
    *outcome = Outcome::kNoLinearPoint;
    if (!start) return std::nullopt;
    x = RefineAngularError(rays, *start, options.max_iterations);
    errors = ViewErrors(views, x, camera);
    const auto worst = std::max_element(errors.begin(), errors.end());
    if (*worst <= options.max_view_error_px) break;
    views.erase(views.begin() + (worst - errors.begin()));
  }
  double sum_sq = 0, weighted_sum_sq = 0;
  for (size_t i = 0; i < views.size(); ++i) {
    sum_sq += errors[i] * errors[i];
    weighted_sum_sq += views[i].ray.weight * errors[i] * errors[i];
  }
  const double n = static_cast<double>(views.size());
  const double rms = std::sqrt(sum_sq / n);
  *outcome = Outcome::kReprojection;
  if (!(rms <= options.max_reprojection_rms_px)) return std::nullopt;
  const double angle = WidestAngleDeg(views, x);
  *outcome = Outcome::kNarrowAngle;
  if (!(angle >= options.min_angle_deg)) return std::nullopt;

  const std::vector<FeatureRay> rays = RaysOf(views);
  const Eigen::Matrix3d normal = AngularNormalMatrix(rays, x);
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(normal);
  const double smallest = eigen.eigenvalues()(0);
  *outcome = Outcome::kPredictedSigma;
  if (!(smallest > 0)) return std::nullopt;
  double nearest = std::numeric_limits<double>::infinity();
  for (const View& v : views) nearest = std::min(nearest, (x - v.ray.cam_from_world.Center()).norm());
  const double predicted_sigma = options.feature_sigma_px / camera.fx / std::sqrt(smallest);
  if (!(predicted_sigma <= options.max_relative_sigma * nearest)) return std::nullopt;

  *outcome = Outcome::kPoint;
  FeaturePoint p;
  p.track = track.id;
  p.position = x;
  p.reprojection_rms_px = rms;
  p.max_angle_deg = angle;
  // 2n residuals, 3 parameters: the RMS underestimates the noise by that.
  // Weighted, it is the noise of a view of weight 1.
  const double weighted_rms = std::sqrt(weighted_sum_sq / n);
  const double noise_px = std::max({weighted_rms * std::sqrt(2 * n / std::max(1.0, 2 * n - 3)), options.feature_sigma_px,
                                    options.covariance_floor_px});
  const double sigma = noise_px / camera.fx;
  p.covariance = sigma * sigma * normal.inverse();
  Eigen::Vector3d rgb = Eigen::Vector3d::Zero();
  for (const View& v : views) {
    p.observations.emplace_back(v.observation.frame, v.observation.pixel);
    rgb += Eigen::Vector3d(v.observation.rgb[0], v.observation.rgb[1], v.observation.rgb[2]);
  }
  rgb /= n;
  for (int c = 0; c < 3; ++c) p.rgb[static_cast<size_t>(c)] = static_cast<std::uint8_t>(std::lround(rgb(c)));
  return p;
}

}  // namespace

std::vector<FeaturePoint> TriangulateTracks(const std::vector<FeatureTrack>& tracks, const PoseMap& cam_from_world,
                                            const CameraModel& camera, const TrackTriangulationOptions& options, int threads,
                                            TrackTriangulationStats* stats) {
  std::vector<std::optional<FeaturePoint>> slots(tracks.size());
  std::vector<Outcome> outcomes(tracks.size(), Outcome::kTooFewViews);
  ParallelFor(tracks.size(), threads, [&](size_t t) {
    const FeatureTrack& track = tracks[t];
    std::vector<View> views;
    std::vector<Eigen::Vector2d> pixels;
    for (const TrackObservation& o : track.observations) {
      const auto pose = cam_from_world.find(o.frame);
      if (pose == cam_from_world.end()) continue;
      const double sigma_px = std::max(o.sigma_px, options.feature_sigma_px);
      const double weight = (options.feature_sigma_px / sigma_px) * (options.feature_sigma_px / sigma_px);
      views.push_back({{pose->second, Eigen::Vector3d::UnitZ(), weight}, o});
      pixels.push_back(o.pixel);
    }
    if (static_cast<int>(views.size()) < options.min_views) return;
    const std::vector<Eigen::Vector2d> normalized = camera.PixelsToNormalized(pixels);
    for (size_t i = 0; i < views.size(); ++i) views[i].ray.bearing = normalized[i].homogeneous().normalized();
    slots[t] = TriangulateOne(track, std::move(views), camera, options, &outcomes[t]);
  });
  if (stats != nullptr) {
    for (const Outcome outcome : outcomes) Count(outcome, stats);
  }
  std::vector<FeaturePoint> points;
  for (std::optional<FeaturePoint>& p : slots) {
    if (p) points.push_back(std::move(*p));
  }
  std::sort(points.begin(), points.end(), [](const FeaturePoint& a, const FeaturePoint& b) { return a.track < b.track; });
  return points;
}

}  // namespace tagsfm
