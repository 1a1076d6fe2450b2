#pragma once
// A first-principles error model for target-based reconstruction, checked
// against the Monte-Carlo sweeps of `tagsfm analyze` (docs/analysis.md).
//
// Everything here is first order (small noise): image noise is isotropic
// Gaussian with standard deviation sigma px; a 3D target whose position is
// uncertain by target_noise_m per axis acts like extra image noise of about
// focal * target_noise_m / depth px. All errors are ROOT-MEAN-SQUARE values
// (the square root of the expected squared error), which is what a
// covariance predicts; the mean of the error norm is a little smaller
// (x0.886 for an isotropic 2D error, x0.921 for an isotropic 3D one).
//
// The live feedback uses the helpers at the bottom to turn the current view
// into advice: "move closer than X m", "need N more targets in view".
#include <optional>
#include <vector>

#include <Eigen/Core>

#include "tagsfm/core/result.h"

namespace tagsfm {

// ---- Points ---------------------------------------------------------------

// Error of a point placed on a noisy viewing ray at its true distance (the
// procedure of the paper's section 4.1.1): RMS = depth * sigma / focal * sqrt(2)
// for a point on the optical axis (the two image axes add up).
double PointErrorAlongRayRms(double depth_m, double focal_px, double sigma_px);

// One observation of a point: the viewing ray's unit direction and length
// (camera centre to point) and the angular noise of the ray (sigma / focal).
struct RayObservation {
  Eigen::Vector3d direction;  // unit, world frame
  double distance_m = 0;
  double angular_sigma_rad = 0;
};

// 3x3 covariance of a point triangulated (least squares) from its rays:
// the inverse of the sum of (I - d d^T) / (distance * angular_sigma)^2.
// An error when fewer than two rays or the rays are (nearly) parallel.
Result<Eigen::Matrix3d> TriangulatedPointCovariance(const std::vector<RayObservation>& rays);

// RMS 3D error of a point seen by two cameras at the same distance whose rays
// meet at `baseline_angle_rad`: depth^2 sigma_l^2 [1/(2cos^2(b/2)) + 1/(2sin^2(b/2)) + 1/2]
// with sigma_l = sigma/focal. Grows like depth/angle for small angles.
double TriangulatedPointErrorRms(double depth_m, double focal_px, double sigma_px, double baseline_angle_rad);

// ---- Camera pose ----------------------------------------------------------

// 6x6 covariance of a camera pose estimated by maximum likelihood (EPnP then
// Levenberg-Marquardt) from targets at known positions in the camera frame.
// Parameters: rotation omega (rad, first three) and translation delta (m) of
// a perturbation applied in the camera frame, X' = X + omega x X + delta, so
// that the camera centre moves by |delta| and the orientation by |omega|.
// Each point may carry its own image noise (px). An error when the geometry
// does not fix the pose (fewer than 3 points, all collinear, behind camera).
Result<Eigen::Matrix<double, 6, 6>> PoseCovariance(const std::vector<Eigen::Vector3d>& points_in_cam,
                                                   double focal_px, const std::vector<double>& sigma_px);

struct PoseErrorRms {
  double rotation_deg = 0;   // RMS rotation angle
  double rotation_eq2 = 0;   // RMS of the paper's eq. 2, |q_est - q_true| = 2 sin(angle/4)
  double position_m = 0;     // RMS camera-centre error (eq. 3 applied to centres)
};
PoseErrorRms PoseErrorFromCovariance(const Eigen::Matrix<double, 6, 6>& covariance);

// What the live feedback knows about a view, in summary.
struct ViewConditions {
  double depth_m = 5;          // mean distance camera -> visible targets
  double focal_px = 1000;
  double image_noise_px = 0.5; // corner / feature localisation sigma
  double target_noise_m = 0;   // sigma of the 3D target positions (per axis)
  int num_targets = 20;        // 2D-3D correspondences in view (tag corners count one each)
  double spread_px = 200;      // RMS image distance of the targets from their centroid
  double depth_relief = 0.1;   // RMS of (Z_i - mean Z) / mean Z over the targets

  // Names the first wrong field.
  Status Check() const;
};

// Pose error of a view from its summary: the covariance of a canonical view
// with those statistics (targets evenly spread over a disc in the image,
// depths evenly spread over the relief). An error when Check() fails.
Result<PoseErrorRms> PredictPoseError(const ViewConditions& view);

// RMS 3D error of a feature point triangulated from two such views whose rays
// meet at baseline_angle_rad: the triangulation error with the image noise
// inflated by the pose uncertainty. A pose fitted to n points predicts the
// image of a point among them to within sigma_eff^2 * 3/n on average (6
// parameters from 2n measurements), so sigma_point^2 = sigma_eff^2 (1 + 3/n),
// where sigma_eff^2 = sigma^2 + (focal * target_noise / depth)^2.
Result<double> PredictFeaturePointErrorRms(const ViewConditions& view, double baseline_angle_rad);

// ---- Advice for the operator ---------------------------------------------

// Largest depth at which a feature point triangulated at baseline_angle_rad
// stays within target_error_m (RMS): the error is proportional to depth at
// fixed angle, so this is exact within the model. An error for bad input.
Result<double> MaxDepthForPointError(double target_error_m, const ViewConditions& view,
                                     double baseline_angle_rad);

// Largest depth at which the camera position error stays within
// target_position_m, for targets spread over an object of RMS radius
// object_radius_m (so the image spread shrinks as f * radius / depth).
// std::nullopt when even at 1% of the current depth the goal is not met.
Result<std::optional<double>> MaxDepthForPoseError(double target_position_m, const ViewConditions& view,
                                                   double object_radius_m);

// Smallest number of targets (same spread, depth, noise) for which the
// predicted rotation error is within target_rotation_deg AND the position
// error within target_position_m. std::nullopt when more than max_targets
// would be needed.
Result<std::optional<int>> TargetsNeeded(double target_rotation_deg, double target_position_m,
                                         const ViewConditions& view, int max_targets = 5000);

}  // namespace tagsfm
