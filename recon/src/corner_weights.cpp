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

CornerNoiseModel FitCornerNoise(std::vector<std::pair<double, double>> variance_and_squared_error, double redundancy) {
  CornerNoiseModel model;
  const size_t n = variance_and_squared_error.size();
  if (n < 64 || !(redundancy > 0)) return model;
  std::sort(variance_and_squared_error.begin(), variance_and_squared_error.end());
  const size_t bins = std::clamp<size_t>(n / 100, 4, 16);
  std::vector<double> x, y;  // per bin: median predicted variance, robust residual variance
  for (size_t b = 0; b < bins; ++b) {
    const size_t begin = b * n / bins, end = (b + 1) * n / bins;
    std::vector<double> squared;
    for (size_t i = begin; i < end; ++i) squared.push_back(variance_and_squared_error[i].second);
    std::nth_element(squared.begin(), squared.begin() + squared.size() / 2, squared.end());
    x.push_back(variance_and_squared_error[(begin + end) / 2].first);
    y.push_back(squared[squared.size() / 2] / (2 * std::log(2.0)) / redundancy);
  }
  // Least squares y = a x + c with a, c >= 0 (a = scale^2, c = floor^2).
  double sx = 0, sy = 0, sxx = 0, sxy = 0;
  for (size_t b = 0; b < bins; ++b) {
    sx += x[b];
    sy += y[b];
    sxx += x[b] * x[b];
    sxy += x[b] * y[b];
  }
  if (!(sxx > 0)) return model;
  const double m = static_cast<double>(bins), det = m * sxx - sx * sx;
  const bool spread = det > 1e-12 * m * sxx;  // else every bin predicts the same: all in the scale
  double a = spread ? (m * sxy - sx * sy) / det : sxy / sxx;
  double c = spread ? (sy - a * sx) / m : 0.0;
  if (c < 0) {
    c = 0;
    a = sxy / sxx;
  }
  if (a < 0) {
    a = 0;
    c = sy / m;
  }
  model.scale = std::sqrt(a);
  model.floor_px = std::sqrt(c);
  return model;
}

}  // namespace tagsfm
