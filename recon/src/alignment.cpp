#include "tagsfm/recon/alignment.h"

#include <cmath>

#include <Eigen/Geometry>

namespace tagsfm {

Alignment AlignPoints(const std::vector<Eigen::Vector3d>& estimate, const std::vector<Eigen::Vector3d>& truth,
                      bool with_scale) {
  Alignment out;
  const size_t n = std::min(estimate.size(), truth.size());
  if (n < 3) return out;
  Eigen::Matrix3Xd src(3, n), dst(3, n);
  for (size_t i = 0; i < n; ++i) {
    src.col(static_cast<Eigen::Index>(i)) = estimate[i];
    dst.col(static_cast<Eigen::Index>(i)) = truth[i];
  }
  const Eigen::Matrix4d t = Eigen::umeyama(src, dst, with_scale);
  const Eigen::Matrix3d sr = t.block<3, 3>(0, 0);
  out.scale = with_scale ? std::cbrt(sr.determinant()) : 1.0;
  out.truth_from_estimate = Rigid3d(Eigen::Quaterniond(sr / out.scale), t.block<3, 1>(0, 3));
  double sum = 0;
  for (size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d mapped = out.scale * (out.truth_from_estimate.rotation * estimate[i]) +
                                   out.truth_from_estimate.translation;
    sum += (mapped - truth[i]).squaredNorm();
  }
  out.rms_m = std::sqrt(sum / static_cast<double>(n));
  return out;
}

}  // namespace tagsfm
