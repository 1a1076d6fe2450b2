#pragma once
// Each tag corner's residual weight from the detector's covariance of it
// (TagDetection::corner_covariance, from the edge fit): corners of small,
// blurred, noisy or strongly tilted tags count for what they are worth. A
// weight W whitens a corner's residual r to W r with W^T W = ref^2 C^-1:
// a corner at the reference sigma keeps the weight of the unweighted
// adjustment, so robust losses keep their scale in pixels.
#include <array>
#include <utility>
#include <vector>

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

// The corners' errors against their covariance C, as scale^2 C + floor^2
// (a lens or a print the model does not know adds the floor; an edge fit
// optimistic by a factor the scale). `variance_and_squared_error`: each
// corner's predicted per-axis variance (trace C / 2, px^2) and squared 2D
// residual (px^2); `redundancy`: the residuals' share of the errors'
// variance (1 - parameters / observations). The corners are binned by
// their predicted variance; each bin's robust variance (median squared 2D
// residual over 2 ln 2, divided by the redundancy) is fitted as a line in
// the bin's predicted variance, both terms >= 0. Fewer than 64 corners:
// scale 1, no floor.
CornerNoiseModel FitCornerNoise(std::vector<std::pair<double, double>> variance_and_squared_error, double redundancy);

}  // namespace tagsfm
