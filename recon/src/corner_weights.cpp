#include "tagsfm/recon/corner_weights.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include <Eigen/Eigenvalues>

namespace tagsfm {

Eigen::Matrix2d CornerWeight(const Eigen::Matrix2d& covariance, double reference_sigma_px) {
  if (!covariance.allFinite() || !(covariance.determinant() > 0) || !(covariance(0, 0) > 0)) {
    return Eigen::Matrix2d::Identity();
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eigen(covariance);
  if (eigen.info() != Eigen::Success) return Eigen::Matrix2d::Identity();
  const double reference_variance = reference_sigma_px * reference_sigma_px;
  Eigen::Vector2d scale;
  for (int k = 0; k < 2; ++k) {
    const double variance = std::clamp(eigen.eigenvalues()(k), reference_variance / 25.0, 25.0 * reference_variance);
    scale(k) = reference_sigma_px / std::sqrt(variance);
  }
  return scale.asDiagonal() * eigen.eigenvectors().transpose();
}

void SetCornerWeights(const std::array<Eigen::Matrix2d, 4>& covariance_in, const CameraModel& camera,
                      double reference_sigma_px, double floor_sigma_px, TagObservation* obs) {
  std::array<Eigen::Matrix2d, 4> covariance = covariance_in;
  for (Eigen::Matrix2d& c : covariance) {
    if (c.determinant() > 0) c += floor_sigma_px * floor_sigma_px * Eigen::Matrix2d::Identity();
  }
  // The undistortion's Jacobian by central differences over a pixel: four
  // probes a corner, one batched call.
  constexpr double kStep = 0.5;
  std::vector<Eigen::Vector2d> probes;
  probes.reserve(16);
  for (int k = 0; k < 4; ++k) {
    for (int axis = 0; axis < 2; ++axis) {
      const Eigen::Vector2d d = kStep * Eigen::Vector2d::Unit(axis);
      probes.push_back(obs->pixels[k] + d);
      probes.push_back(obs->pixels[k] - d);
    }
  }
  const std::vector<Eigen::Vector2d> normalized = camera.PixelsToNormalized(probes);
  const Eigen::Vector2d focal(camera.fx, camera.fy);
  for (int k = 0; k < 4; ++k) {
    obs->weight_pixels[k] = CornerWeight(covariance[k], reference_sigma_px);
    Eigen::Matrix2d jacobian;
    for (int axis = 0; axis < 2; ++axis) {
      const size_t i = static_cast<size_t>(4 * k + 2 * axis);
      jacobian.col(axis) = focal.cwiseProduct(normalized[i] - normalized[i + 1]) / (2 * kStep);
    }
    const Eigen::Matrix2d undistorted = jacobian * covariance[k] * jacobian.transpose();
    obs->weight_undistorted[k] =
        jacobian.allFinite() ? CornerWeight(undistorted, reference_sigma_px) : Eigen::Matrix2d::Identity();
  }
}

}  // namespace tagsfm
