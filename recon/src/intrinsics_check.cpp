#include "tagsfm/recon/intrinsics_check.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

namespace tagsfm {

Status IntrinsicsCheckOptions::Check() const {
  if (!(max_focal_sigma_rel > 0)) return MakeError("intrinsics_check.max_focal_sigma_rel must be > 0");
  if (!(max_principal_point_sigma_px > 0)) return MakeError("intrinsics_check.max_principal_point_sigma_px must be > 0");
  if (!(max_distortion_sigma_px > 0)) return MakeError("intrinsics_check.max_distortion_sigma_px must be > 0");
  return Status::Ok();
}

std::array<double, 6> IntrinsicsSigma(const Eigen::Matrix<double, 6, 6>& covariance) {
  std::array<double, 6> sigma;
  for (int k = 0; k < 6; ++k) sigma[static_cast<size_t>(k)] = std::sqrt(std::max(0.0, covariance(k, k)));
  return sigma;
}

double DistortionSigmaAtRadiusPx(const CameraModel& camera, const Eigen::Matrix<double, 6, 6>& covariance, double radius_px) {
  // At normalised radius r the displacement is r_px (k1 r^2 + k2 r^4).
  const double r2 = std::pow(radius_px / (0.5 * (camera.fx + camera.fy)), 2);
  const Eigen::Vector2d gradient(radius_px * r2, radius_px * r2 * r2);  // d displacement / d (k1, k2)
  const double variance = gradient.dot(covariance.bottomRightCorner<2, 2>() * gradient);
  return std::sqrt(std::max(0.0, variance));
}

double CornerRadiusPx(const CameraModel& camera) {
  double r = 0;
  for (double x : {-0.5, camera.width - 0.5}) {
    for (double y : {-0.5, camera.height - 0.5}) r = std::max(r, std::hypot(x - camera.cx, y - camera.cy));
  }
  return r;
}

double ObservedRadiusPx(std::vector<Eigen::Vector2d> pixels, const CameraModel& camera) {
  if (pixels.empty()) return 0;
  std::vector<double> r;
  r.reserve(pixels.size());
  for (const Eigen::Vector2d& p : pixels) r.push_back(std::hypot(p.x() - camera.cx, p.y() - camera.cy));
  const auto at = r.begin() + static_cast<long>(0.95 * static_cast<double>(r.size() - 1));
  std::nth_element(r.begin(), at, r.end());
  return *at;
}

std::vector<std::string> UnconstrainedIntrinsics(const CameraModel& camera, const Eigen::Matrix<double, 6, 6>& covariance,
                                                 double observed_radius_px, const IntrinsicsCheckOptions& options) {
  const std::array<double, 6> sigma = IntrinsicsSigma(covariance);
  std::vector<std::string> out;
  char line[160];
  const char* names[] = {"fx", "fy", "cx", "cy"};
  const double values[] = {camera.fx, camera.fy};
  for (int k = 0; k < 2; ++k) {
    const double rel = sigma[static_cast<size_t>(k)] / values[k];
    if (!(rel <= options.max_focal_sigma_rel)) {
      std::snprintf(line, sizeof line, "%s: sigma %.2f px (%.3f %%), more than %.3f %%", names[k], sigma[static_cast<size_t>(k)],
                    100 * rel, 100 * options.max_focal_sigma_rel);
      out.push_back(line);
    }
  }
  for (int k = 2; k < 4; ++k) {
    if (!(sigma[static_cast<size_t>(k)] <= options.max_principal_point_sigma_px)) {
      std::snprintf(line, sizeof line, "%s: sigma %.2f px, more than %.2f px", names[k], sigma[static_cast<size_t>(k)],
                    options.max_principal_point_sigma_px);
      out.push_back(line);
    }
  }
  const double distortion = DistortionSigmaAtRadiusPx(camera, covariance, observed_radius_px);
  if (!(distortion <= options.max_distortion_sigma_px)) {
    std::snprintf(line, sizeof line, "distortion (k1, k2): sigma %.2f px %.0f px from the centre, more than %.2f px",
                  distortion, observed_radius_px, options.max_distortion_sigma_px);
    out.push_back(line);
  }
  return out;
}

std::optional<IntrinsicsUncertainty> JudgeIntrinsics(const ReconstructionResult& result, const IntrinsicsCheckOptions& options) {
  if (!result.intrinsics_covariance) return std::nullopt;
  const Eigen::Matrix<double, 6, 6>& covariance = *result.intrinsics_covariance;
  std::vector<Eigen::Vector2d> seen;
  for (const FrameState& frame : result.frames) {
    if (!frame.registered) continue;
    for (const TagObservation& obs : frame.tags) {
      if (!obs.outlier) seen.insert(seen.end(), obs.pixels.begin(), obs.pixels.end());
    }
  }
  IntrinsicsUncertainty out;
  out.sigma = IntrinsicsSigma(covariance);
  out.observed_radius_px = ObservedRadiusPx(std::move(seen), result.camera);
  out.distortion_sigma_px = DistortionSigmaAtRadiusPx(result.camera, covariance, out.observed_radius_px);
  out.distortion_sigma_corner_px = DistortionSigmaAtRadiusPx(result.camera, covariance, CornerRadiusPx(result.camera));
  out.unconstrained = UnconstrainedIntrinsics(result.camera, covariance, out.observed_radius_px, options);
  return out;
}

}  // namespace tagsfm
