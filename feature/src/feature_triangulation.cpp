#include "tagsfm/feature/feature_triangulation.h"

#include <algorithm>
#include <cmath>
#include <unordered_map>

#include <Eigen/Dense>

namespace tagsfm {

Status FeatureTriangulationOptions::Check() const {
  if (min_track_length < 2) return MakeError("features.min_track_length must be >= 2");
  if (!(min_angle_deg > 0 && min_angle_deg < 90)) return MakeError("features.min_angle_deg must be in (0, 90)");
  if (!(max_reprojection_px > 0)) return MakeError("features.max_reprojection_px must be > 0");
  if (max_iterations < 1) return MakeError("features.max_iterations must be >= 1");
  return Status::Ok();
}

std::optional<Eigen::Vector3d> TriangulateLinear(const std::vector<FeatureRay>& rays) {
  if (rays.size() < 2) return std::nullopt;
  // Each ray gives two equations: the point's direction has no component
  // across the bearing (cross product rows, the two best conditioned).
  Eigen::MatrixXd a(2 * rays.size(), 4);
  for (size_t i = 0; i < rays.size(); ++i) {
    Eigen::Matrix<double, 3, 4> p;
    p.leftCols<3>() = rays[i].cam_from_world.RotationMatrix();
    p.col(3) = rays[i].cam_from_world.translation;
    const Eigen::Vector3d b = rays[i].bearing;
    // Two unit vectors across the bearing.
    const Eigen::Vector3d u = b.unitOrthogonal();
    const Eigen::Vector3d v = b.cross(u);
    a.row(static_cast<Eigen::Index>(2 * i)) = u.transpose() * p;
    a.row(static_cast<Eigen::Index>(2 * i + 1)) = v.transpose() * p;
  }
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(a, Eigen::ComputeFullV);
  const Eigen::Vector4d x = svd.matrixV().col(3);
  const Eigen::Vector4d sv = Eigen::Vector4d(svd.singularValues().head<4>());
  // Parallel rays: the null space is two-dimensional (a point at infinity
  // along them and the line of them).
  if (!(sv(2) > 1e-9 * sv(0)) || std::abs(x(3)) < 1e-12) return std::nullopt;
  return Eigen::Vector3d(x.head<3>() / x(3));
}

namespace {

// One ray's angular residual (the point's direction in the bearing's
// tangent plane: the sine of the angle, in two components) and its Jacobian
// with respect to the world point.
void AngularResidual(const FeatureRay& ray, const Eigen::Vector3d& x, Eigen::Vector2d* residual,
                     Eigen::Matrix<double, 2, 3>* jacobian) {
  const Eigen::Matrix3d r = ray.cam_from_world.RotationMatrix();
  const Eigen::Vector3d xc = r * x + ray.cam_from_world.translation;
  const double n = xc.norm();
  const Eigen::Vector3d dir = xc / n;
  const Eigen::Vector3d u = ray.bearing.unitOrthogonal();
  const Eigen::Vector3d v = ray.bearing.cross(u);
  *residual = Eigen::Vector2d(u.dot(dir), v.dot(dir));
  const Eigen::Matrix3d ddir = (Eigen::Matrix3d::Identity() - dir * dir.transpose()) / n * r;
  jacobian->row(0) = u.transpose() * ddir;
  jacobian->row(1) = v.transpose() * ddir;
}

}  // namespace

Eigen::Matrix3d AngularNormalMatrix(const std::vector<FeatureRay>& rays, const Eigen::Vector3d& point) {
  Eigen::Matrix3d h = Eigen::Matrix3d::Zero();
  Eigen::Vector2d res;
  Eigen::Matrix<double, 2, 3> j;
  for (const FeatureRay& ray : rays) {
    AngularResidual(ray, point, &res, &j);
    if (j.allFinite()) h += ray.weight * (j.transpose() * j);
  }
  return h;
}

Eigen::Vector3d RefineAngularError(const std::vector<FeatureRay>& rays, const Eigen::Vector3d& start, int max_iterations) {
  Eigen::Vector3d x = start;
  for (int iteration = 0; iteration < max_iterations; ++iteration) {
    Eigen::Matrix3d h = Eigen::Matrix3d::Zero();
    Eigen::Vector3d g = Eigen::Vector3d::Zero();
    Eigen::Vector2d res;
    Eigen::Matrix<double, 2, 3> j;
    for (const FeatureRay& ray : rays) {
      AngularResidual(ray, x, &res, &j);
      if (!res.allFinite() || !j.allFinite()) continue;  // the point at a camera's centre
      h += ray.weight * (j.transpose() * j);
      g += ray.weight * (j.transpose() * res);
    }
    const Eigen::Vector3d step = h.ldlt().solve(-g);
    if (!step.allFinite()) break;
    x += step;
    if (step.norm() < 1e-10 * (1.0 + x.norm())) break;
  }
  return x;
}

std::vector<FeaturePoint> TriangulateFeatureTracks(const std::vector<FeatureSet>& sets, const PoseMap& cam_from_world,
                                                   const CameraModel& camera, const FeatureTriangulationOptions& options) {
  struct Track {
    std::vector<FeatureRay> rays;
    std::vector<std::pair<FrameId, Eigen::Vector2d>> observations;
    std::array<std::uint8_t, 3> rgb{0, 0, 0};
  };
  std::unordered_map<TrackId, Track> tracks;
  for (const FeatureSet& set : sets) {
    const auto pose = cam_from_world.find(set.frame);
    if (pose == cam_from_world.end()) continue;
    std::vector<Eigen::Vector2d> pixels;
    pixels.reserve(set.features.size());
    for (const FeatureObservation& f : set.features) pixels.push_back(f.pixel);
    const std::vector<Eigen::Vector2d> normalized = camera.PixelsToNormalized(pixels);
    for (size_t i = 0; i < set.features.size(); ++i) {
      const FeatureObservation& f = set.features[i];
      Track& t = tracks[f.track];
      t.rays.push_back({pose->second, normalized[i].homogeneous().normalized()});
      t.observations.emplace_back(set.frame, f.pixel);
      t.rgb = f.rgb;
    }
  }
  const double min_cos = std::cos(options.min_angle_deg * M_PI / 180.0);
  std::vector<FeaturePoint> points;
  for (auto& [id, track] : tracks) {
    if (static_cast<int>(track.rays.size()) < options.min_track_length) continue;
    // The widest angle between two of the rays, in the world frame.
    double widest_cos = 1.0;
    std::vector<Eigen::Vector3d> world_rays;
    for (const FeatureRay& ray : track.rays) world_rays.push_back(ray.cam_from_world.rotation.conjugate() * ray.bearing);
    for (size_t i = 0; i < world_rays.size(); ++i) {
      for (size_t k = i + 1; k < world_rays.size(); ++k) widest_cos = std::min(widest_cos, world_rays[i].dot(world_rays[k]));
    }
    if (widest_cos > min_cos) continue;
    const std::optional<Eigen::Vector3d> start = TriangulateLinear(track.rays);
    if (!start) continue;
    const Eigen::Vector3d x = RefineAngularError(track.rays, *start, options.max_iterations);
    double sum_sq = 0;
    bool in_front = true;
    for (size_t i = 0; i < track.rays.size() && in_front; ++i) {
      const Eigen::Vector3d xc = track.rays[i].cam_from_world * x;
      if (!(xc.z() > 0)) {
        in_front = false;
        break;
      }
      sum_sq += (camera.Project(xc) - track.observations[i].second).squaredNorm();
    }
    if (!in_front) continue;
    const double rms = std::sqrt(sum_sq / static_cast<double>(track.rays.size()));
    if (!(rms <= options.max_reprojection_px)) continue;
    FeaturePoint p;
    p.track = id;
    p.position = x;
    p.rgb = track.rgb;
    p.reprojection_rms_px = rms;
    p.max_angle_deg = std::acos(std::clamp(widest_cos, -1.0, 1.0)) * 180.0 / M_PI;
    const double sigma = std::max(rms, 0.1) / camera.fx;
    p.covariance = sigma * sigma * AngularNormalMatrix(track.rays, x).inverse();
    p.observations = std::move(track.observations);
    points.push_back(std::move(p));
  }
  std::sort(points.begin(), points.end(), [](const FeaturePoint& a, const FeaturePoint& b) { return a.track < b.track; });
  return points;
}

}  // namespace tagsfm
