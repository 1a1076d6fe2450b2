// First-order error propagation for points and camera poses; see error_model.h.
#include "tagsfm/recon/error_model.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <string>

#include <Eigen/Dense>

namespace tagsfm {
namespace {

using Matrix6d = Eigen::Matrix<double, 6, 6>;
using Matrix26d = Eigen::Matrix<double, 2, 6>;

constexpr double kRadToDeg = 180.0 / std::numbers::pi;
// The low-discrepancy sequences that spread a canonical view's targets.
constexpr double kGoldenAngleRad = 2.399963229728653;  // pi (3 - sqrt 5)
constexpr double kPlasticInverse = 0.7548776662466927; // 1 / plastic number

// d(pixel)/d(omega, delta) for a point in the camera frame (see PoseCovariance).
Matrix26d ProjectionJacobian(const Eigen::Vector3d& p, double focal_px) {
  const double inv_z = 1.0 / p.z();
  Eigen::Matrix<double, 2, 3> d_pixel_d_point;
  d_pixel_d_point << inv_z, 0, -p.x() * inv_z * inv_z,  //
      0, inv_z, -p.y() * inv_z * inv_z;
  d_pixel_d_point *= focal_px;
  Eigen::Matrix3d minus_skew;  // d(omega x p)/d(omega) = -[p]x
  minus_skew << 0, p.z(), -p.y(),  //
      -p.z(), 0, p.x(),            //
      p.y(), -p.x(), 0;
  Matrix26d jacobian;
  jacobian.leftCols<3>() = d_pixel_d_point * minus_skew;
  jacobian.rightCols<3>() = d_pixel_d_point;
  return jacobian;
}

// Image noise of each target: its own plus its 3D position noise projected,
// f/Z (dX - x dZ) per axis, averaged over the two axes.
std::vector<double> EffectiveSigmas(const std::vector<Eigen::Vector3d>& points_in_cam, const ViewConditions& view) {
  std::vector<double> sigmas;
  sigmas.reserve(points_in_cam.size());
  for (const Eigen::Vector3d& p : points_in_cam) {
    const double projected = view.focal_px * view.target_noise_m / p.z();
    const double off_axis_sq = (p.x() * p.x() + p.y() * p.y()) / (p.z() * p.z());
    sigmas.push_back(std::sqrt(view.image_noise_px * view.image_noise_px +
                               projected * projected * (1.0 + 0.5 * off_axis_sq)));
  }
  return sigmas;
}

// Targets evenly spread over a disc of RMS radius spread_px around the image
// centre (sunflower pattern), depths evenly spread with RMS relief.
std::vector<Eigen::Vector3d> CanonicalTargets(const ViewConditions& view) {
  const int n = view.num_targets;
  const double disc_radius_px = view.spread_px * std::sqrt(2.0);  // uniform disc: RMS = R / sqrt 2
  const double depth_half_range = view.depth_relief * std::sqrt(3.0);  // uniform: RMS = a / sqrt 3
  std::vector<Eigen::Vector3d> points;
  points.reserve(n);
  for (int k = 0; k < n; ++k) {
    const double r_px = disc_radius_px * std::sqrt((k + 0.5) / n);
    const double angle = k * kGoldenAngleRad;
    const double u = 2.0 * std::fmod((k + 0.5) * kPlasticInverse, 1.0) - 1.0;
    const double z = view.depth_m * (1.0 + depth_half_range * u);
    points.emplace_back(r_px * std::cos(angle) / view.focal_px * z, r_px * std::sin(angle) / view.focal_px * z, z);
  }
  return points;
}

Status CheckPositive(double value, const char* name) {
  if (!(value > 0) || !std::isfinite(value)) {
    return MakeError(std::string(name) + " must be > 0 (got " + std::to_string(value) + ")");
  }
  return Status::Ok();
}

}  // namespace

double PointErrorAlongRayRms(double depth_m, double focal_px, double sigma_px) {
  return depth_m * sigma_px / focal_px * std::sqrt(2.0);
}

Result<Eigen::Matrix3d> TriangulatedPointCovariance(const std::vector<RayObservation>& rays) {
  if (rays.size() < 2) return MakeError("triangulation needs at least 2 rays (got " + std::to_string(rays.size()) + ")");
  Eigen::Matrix3d information = Eigen::Matrix3d::Zero();
  for (const RayObservation& ray : rays) {
    const double lateral_sigma = ray.distance_m * ray.angular_sigma_rad;
    if (!(lateral_sigma > 0)) return MakeError("triangulation ray with zero distance or angular noise");
    const Eigen::Vector3d d = ray.direction.normalized();
    information += (Eigen::Matrix3d::Identity() - d * d.transpose()) / (lateral_sigma * lateral_sigma);
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(information);
  if (eigen.eigenvalues()(0) <= 1e-12 * eigen.eigenvalues()(2)) {
    return MakeError("triangulation rays are parallel: the point's depth is undetermined");
  }
  return Eigen::Matrix3d(information.inverse());
}

double TriangulatedPointErrorRms(double depth_m, double focal_px, double sigma_px, double baseline_angle_rad) {
  const double lateral = depth_m * sigma_px / focal_px;
  const double c = std::cos(0.5 * baseline_angle_rad);
  const double s = std::sin(0.5 * baseline_angle_rad);
  return lateral * std::sqrt(0.5 / (c * c) + 0.5 / (s * s) + 0.5);
}

Result<Matrix6d> PoseCovariance(const std::vector<Eigen::Vector3d>& points_in_cam, double focal_px,
                                const std::vector<double>& sigma_px) {
  if (points_in_cam.size() < 3) {
    return MakeError("pose covariance needs at least 3 targets (got " + std::to_string(points_in_cam.size()) + ")");
  }
  if (sigma_px.size() != points_in_cam.size()) return MakeError("pose covariance: one sigma per target needed");
  if (Status focal_ok = CheckPositive(focal_px, "focal_px"); !focal_ok) return focal_ok.error();
  const bool all_zero = std::all_of(sigma_px.begin(), sigma_px.end(), [](double s) { return s == 0; });
  const bool all_positive = std::all_of(sigma_px.begin(), sigma_px.end(), [](double s) { return s > 0; });
  if (!all_zero && !all_positive) return MakeError("pose covariance: image noise must be all zero or all > 0");
  Matrix6d information = Matrix6d::Zero();
  for (size_t i = 0; i < points_in_cam.size(); ++i) {
    if (!(points_in_cam[i].z() > 0)) return MakeError("pose covariance: target " + std::to_string(i) + " is behind the camera");
    const Matrix26d j = ProjectionJacobian(points_in_cam[i], focal_px);
    const double weight = all_zero ? 1.0 : 1.0 / (sigma_px[i] * sigma_px[i]);
    information.noalias() += weight * j.transpose() * j;
  }
  const Eigen::SelfAdjointEigenSolver<Matrix6d> eigen(information);
  if (eigen.eigenvalues()(0) <= 1e-12 * eigen.eigenvalues()(5)) {
    return MakeError("pose covariance: the targets do not fix the pose (degenerate geometry)");
  }
  if (all_zero) return Matrix6d(Matrix6d::Zero());
  return Matrix6d(eigen.eigenvectors() * eigen.eigenvalues().cwiseInverse().asDiagonal() *
                  eigen.eigenvectors().transpose());
}

PoseErrorRms PoseErrorFromCovariance(const Matrix6d& covariance) {
  PoseErrorRms error;
  const double rotation_rad = std::sqrt(std::max(0.0, covariance.topLeftCorner<3, 3>().trace()));
  error.rotation_deg = rotation_rad * kRadToDeg;
  error.rotation_eq2 = 2.0 * std::sin(0.25 * rotation_rad);
  error.position_m = std::sqrt(std::max(0.0, covariance.bottomRightCorner<3, 3>().trace()));
  return error;
}

Status ViewConditions::Check() const {
  if (Status s = CheckPositive(depth_m, "depth_m"); !s) return s;
  if (Status s = CheckPositive(focal_px, "focal_px"); !s) return s;
  if (Status s = CheckPositive(spread_px, "spread_px"); !s) return s;
  if (!(image_noise_px >= 0) || !std::isfinite(image_noise_px)) {
    return MakeError("image_noise_px must be >= 0 (got " + std::to_string(image_noise_px) + ")");
  }
  if (!(target_noise_m >= 0) || !std::isfinite(target_noise_m)) {
    return MakeError("target_noise_m must be >= 0 (got " + std::to_string(target_noise_m) + ")");
  }
  if (num_targets < 4) return MakeError("num_targets must be >= 4 (got " + std::to_string(num_targets) + ")");
  if (!(depth_relief >= 0 && depth_relief <= 0.5)) {
    return MakeError("depth_relief must be in [0, 0.5] (got " + std::to_string(depth_relief) + ")");
  }
  return Status::Ok();
}

Result<PoseErrorRms> PredictPoseError(const ViewConditions& view) {
  if (Status ok = view.Check(); !ok) return ok.error();
  const std::vector<Eigen::Vector3d> targets = CanonicalTargets(view);
  Result<Matrix6d> covariance = PoseCovariance(targets, view.focal_px, EffectiveSigmas(targets, view));
  if (!covariance) return covariance.error();
  return PoseErrorFromCovariance(*covariance);
}

Result<double> PredictFeaturePointErrorRms(const ViewConditions& view, double baseline_angle_rad) {
  if (Status ok = view.Check(); !ok) return ok.error();
  if (!(baseline_angle_rad > 0 && baseline_angle_rad < std::numbers::pi)) {
    return MakeError("baseline angle must be in (0, pi) rad (got " + std::to_string(baseline_angle_rad) + ")");
  }
  const double projected_target_noise = view.focal_px * view.target_noise_m / view.depth_m;
  const double pose_sigma_sq = view.image_noise_px * view.image_noise_px + projected_target_noise * projected_target_noise;
  const double point_sigma = std::sqrt(view.image_noise_px * view.image_noise_px + 3.0 * pose_sigma_sq / view.num_targets);
  return TriangulatedPointErrorRms(view.depth_m, view.focal_px, point_sigma, baseline_angle_rad);
}

Result<double> MaxDepthForPointError(double target_error_m, const ViewConditions& view, double baseline_angle_rad) {
  if (Status ok = CheckPositive(target_error_m, "target error"); !ok) return ok.error();
  // The target-noise term projects as f * noise / depth, so keep it in metres
  // by evaluating at the current depth and scaling only the image part.
  Result<double> at_current = PredictFeaturePointErrorRms(view, baseline_angle_rad);
  if (!at_current) return at_current.error();
  if (*at_current == 0) return std::numeric_limits<double>::infinity();
  if (view.target_noise_m == 0) return view.depth_m * target_error_m / *at_current;
  // With target noise the error is sqrt(a Z^2 + b) where b does not depend on Z.
  ViewConditions no_target_noise = view;
  no_target_noise.target_noise_m = 0;
  Result<double> image_part = PredictFeaturePointErrorRms(no_target_noise, baseline_angle_rad);
  if (!image_part) return image_part.error();
  const double a = (*image_part * *image_part) / (view.depth_m * view.depth_m);
  const double b = *at_current * *at_current - *image_part * *image_part;
  if (target_error_m * target_error_m <= b) return 0.0;
  if (a == 0) return std::numeric_limits<double>::infinity();
  return std::sqrt((target_error_m * target_error_m - b) / a);
}

Result<std::optional<double>> MaxDepthForPoseError(double target_position_m, const ViewConditions& view,
                                                   double object_radius_m) {
  if (Status ok = CheckPositive(target_position_m, "target position error"); !ok) return ok.error();
  if (Status ok = CheckPositive(object_radius_m, "object radius"); !ok) return ok.error();
  if (Status ok = view.Check(); !ok) return ok.error();
  const double relief_m = view.depth_relief * view.depth_m;  // the object's depth extent stays the same
  auto position_error_at = [&](double depth_m) -> Result<double> {
    ViewConditions moved = view;
    moved.depth_m = depth_m;
    moved.spread_px = view.focal_px * object_radius_m / depth_m;
    moved.depth_relief = std::min(0.5, relief_m / depth_m);
    Result<PoseErrorRms> error = PredictPoseError(moved);
    if (!error) return error.error();
    return error->position_m;
  };
  double near_m = 0.01 * view.depth_m;
  Result<double> near_error = position_error_at(near_m);
  if (!near_error) return near_error.error();
  if (*near_error > target_position_m) return std::optional<double>();
  double far_m = view.depth_m;
  for (int i = 0; i < 40; ++i) {  // grow until the goal fails (at most 2^40 x)
    Result<double> far_error = position_error_at(far_m);
    if (!far_error) return far_error.error();
    if (*far_error > target_position_m) break;
    near_m = far_m;
    far_m *= 2.0;
  }
  for (int i = 0; i < 60 && far_m - near_m > 1e-6 * far_m; ++i) {  // bisection: error grows with depth
    const double mid_m = 0.5 * (near_m + far_m);
    Result<double> mid_error = position_error_at(mid_m);
    if (!mid_error) return mid_error.error();
    (*mid_error > target_position_m ? far_m : near_m) = mid_m;
  }
  return std::optional<double>(near_m);
}

Result<std::optional<int>> TargetsNeeded(double target_rotation_deg, double target_position_m,
                                         const ViewConditions& view, int max_targets) {
  if (Status ok = CheckPositive(target_rotation_deg, "target rotation error"); !ok) return ok.error();
  if (Status ok = CheckPositive(target_position_m, "target position error"); !ok) return ok.error();
  if (Status ok = view.Check(); !ok) return ok.error();
  auto meets_goal = [&](int n) -> Result<bool> {
    ViewConditions with_n = view;
    with_n.num_targets = n;
    Result<PoseErrorRms> error = PredictPoseError(with_n);
    if (!error) return error.error();
    return error->rotation_deg <= target_rotation_deg && error->position_m <= target_position_m;
  };
  Result<bool> at_max = meets_goal(max_targets);
  if (!at_max) return at_max.error();
  if (!*at_max) return std::optional<int>();
  int low = 3, high = max_targets;  // goal fails at low (or low is below the minimum), holds at high
  while (high - low > 1) {  // errors fall like 1/sqrt(n): bisection on n
    const int mid = low + (high - low) / 2;
    Result<bool> ok = meets_goal(mid);
    if (!ok) return ok.error();
    (*ok ? high : low) = mid;
  }
  return std::optional<int>(high);
}

}  // namespace tagsfm
