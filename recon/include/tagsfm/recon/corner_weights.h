#pragma once
// Each tag corner's residual weight from the detector's covariance of it
// (TagDetection::corner_covariance, from the edge fit): corners of small,
// blurred, noisy or strongly tilted tags count for what they are worth. A
// weight W whitens a corner's residual r to W r with W^T W = ref^2 C^-1:
// a corner at the reference sigma keeps the weight of the unweighted
// adjustment, so robust losses keep their scale in pixels.
#include <array>

#include <Eigen/Core>

#include "tagsfm/core/camera_model.h"
#include "tagsfm/recon/reconstruction.h"

namespace tagsfm {

// W for covariance `covariance` (px^2), its eigenvalues held within 5x of
// the reference sigma either way (a corner is never worth more than 25
// average ones, nor nothing); identity when `covariance` is not positive
// definite (unknown).
Eigen::Matrix2d CornerWeight(const Eigen::Matrix2d& covariance, double reference_sigma_px);

// Sets obs->weight_pixels from the image-pixel covariances, and
// obs->weight_undistorted from them carried through the lens to the
// normalized residuals' units (undistorted pixels: fx, fy times normalized
// coordinates), by the undistortion's Jacobian at each corner.
// `floor_sigma_px` is added to every known covariance (floor^2 I) first:
// what the edge fit's covariance cannot see in any corner.
void SetCornerWeights(const std::array<Eigen::Matrix2d, 4>& covariance, const CameraModel& camera,
                      double reference_sigma_px, double floor_sigma_px, TagObservation* obs);

}  // namespace tagsfm
