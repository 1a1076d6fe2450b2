#pragma once
// Whether the views constrain the adjusted intrinsics: from their
// covariance in the final adjustment (every pose and learned tag free), each
// quantity a user of the camera block relies on, against a limit. A set of
// frontal views at one distance leaves the focal length and the principal
// point free to trade against the poses; tags only near the image centre
// leave the distortion unknown at the borders. `tagsfm calibrate` refuses to
// write such an estimate (unless told to) instead of handing out a
// confident wrong camera block.
#include <array>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "tagsfm/core/camera_model.h"
#include "tagsfm/core/result.h"
#include "tagsfm/recon/reconstruction.h"

namespace tagsfm {

struct IntrinsicsCheckOptions {
  // Limits on one standard deviation beyond which the views do not
  // constrain a parameter for a metric survey: a 2-sigma focal error of
  // 0.4 % scales every depth by that much. Well spread views do far better
  // (20 frames of a box at 640x480: 0.05 %, 0.23 px; frontal views of a
  // wall at one distance: 0.29 % on the focal length).
  double max_focal_sigma_rel = 2e-3;
  double max_principal_point_sigma_px = 2.0;
  // Of the radial distortion's displacement (k1 and k2 together, their
  // correlation included), pixels, as far from the principal point as the
  // targets were seen (ObservedRadiusPx): beyond, the lens is extrapolated
  // by any calibration, and the report says how much.
  double max_distortion_sigma_px = 1.0;

  Status Check() const;  // names the wrong field
};

// The standard deviations of fx, fy, cx, cy (pixels), k1, k2: the
// covariance's diagonal (order as in GlobalAdjustmentSummary).
std::array<double, 6> IntrinsicsSigma(const Eigen::Matrix<double, 6, 6>& covariance);

// Standard deviation of the radial distortion's displacement (pixels) at
// `radius_px` from the principal point.
double DistortionSigmaAtRadiusPx(const CameraModel& camera, const Eigen::Matrix<double, 6, 6>& covariance, double radius_px);
// Distance of the image corner farthest from the principal point, pixels.
double CornerRadiusPx(const CameraModel& camera);
// The 95th percentile of the distances of `pixels` (target corners seen)
// from the principal point; 0 for none.
double ObservedRadiusPx(std::vector<Eigen::Vector2d> pixels, const CameraModel& camera);

// One line per quantity beyond its limit ("cx: sigma 1.8 px, more than
// 0.5 px"), the distortion judged at `observed_radius_px`; empty when the
// views constrain them all.
std::vector<std::string> UnconstrainedIntrinsics(const CameraModel& camera, const Eigen::Matrix<double, 6, 6>& covariance,
                                                 double observed_radius_px, const IntrinsicsCheckOptions& options);

// A result's adjusted intrinsics judged: their sigmas, the distortion's
// sigma where the targets were seen and at the image's corners, and what
// the views leave unconstrained.
struct IntrinsicsUncertainty {
  std::array<double, 6> sigma{};  // fx, fy, cx, cy (px), k1, k2
  double observed_radius_px = 0;  // ObservedRadiusPx of the registered frames' target corners
  double distortion_sigma_px = 0;         // at observed_radius_px
  double distortion_sigma_corner_px = 0;  // at CornerRadiusPx
  std::vector<std::string> unconstrained;  // UnconstrainedIntrinsics
};

// nullopt when the result has no intrinsics covariance.
std::optional<IntrinsicsUncertainty> JudgeIntrinsics(const ReconstructionResult& result, const IntrinsicsCheckOptions& options);

}  // namespace tagsfm
