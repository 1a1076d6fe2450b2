#include "tagsfm/feature/patch_refinement.h"

#include <cmath>
#include <limits>
#include <vector>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>

namespace tagsfm {

Status PatchRefinementOptions::Check() const {
  if (half_window < 2 || half_window > 32) return MakeError("refinement.half_window must be in [2, 32]");
  if (max_iterations < 1) return MakeError("refinement.max_iterations must be >= 1");
  if (!(converged_px > 0)) return MakeError("refinement.converged_px must be > 0");
  if (!(converged_sigma_fraction >= 0 && converged_sigma_fraction <= 1)) {
    return MakeError("refinement.converged_sigma_fraction must be in [0, 1]");
  }
  if (!(sparse_until_px >= 0)) return MakeError("refinement.sparse_until_px must be >= 0 (0: every pixel throughout)");
  if (!(max_shift_px > 0)) return MakeError("refinement.max_shift_px must be > 0");
  if (!(min_correlation >= -1 && min_correlation <= 1)) return MakeError("refinement.min_correlation must be in [-1, 1]");
  if (!(max_sigma_px > 0)) return MakeError("refinement.max_sigma_px must be > 0");
  if (max_level < 0 || max_level > 6) return MakeError("refinement.max_level must be in [0, 6]");
  if (reference_attempts < 1) return MakeError("refinement.reference_attempts must be >= 1");
  if (tilt_retries < 0) return MakeError("refinement.tilt_retries must be >= 0");
  if (!(tilt_step_deg > 0 && tilt_step_deg < 90)) return MakeError("refinement.tilt_step_deg must be in (0, 90)");
  return Status::Ok();
}

namespace {

// Bilinear grey value at (x, y); the caller keeps (x, y) at least one pixel
// inside the image. Coordinates are then positive, so truncation is their
// floor: std::floor is a library call on baseline x86-64 (no SSE4.1), and
// the fits spent 9 % of their time in it (docs/features.md).
inline double Sample(const cv::Mat& image, double x, double y) {
  const int x0 = static_cast<int>(x), y0 = static_cast<int>(y);
  const double fx = x - x0, fy = y - y0;
  const std::uint8_t* r0 = image.ptr<std::uint8_t>(y0) + x0;
  const std::uint8_t* r1 = image.ptr<std::uint8_t>(y0 + 1) + x0;
  return (1 - fy) * ((1 - fx) * r0[0] + fx * r0[1]) + fy * ((1 - fx) * r1[0] + fx * r1[1]);
}

// Bilinear grey value at (x, y) and its central differences over two
// pixels, (S(x+1, y) - S(x-1, y)) / 2 and the same in y, from the 4x4
// pixels round (x, y) read once; the caller keeps (x, y) two pixels inside.
struct SampleWithSlope {
  double value, gx, gy;
};

inline SampleWithSlope SampleAndSlope(const cv::Mat& image, double x, double y) {
  const int x0 = static_cast<int>(x), y0 = static_cast<int>(y);  // positive: truncation is the floor
  const double fx = x - x0, fy = y - y0;
  // rows[r][c]: pixel (x0 + c - 1, y0 + r - 1), each row interpolated in x
  // at the sample's column and one column left and right.
  double left[4], mid[4], right[4];
  for (int r = 0; r < 4; ++r) {
    const std::uint8_t* p = image.ptr<std::uint8_t>(y0 + r - 1) + x0 - 1;
    left[r] = (1 - fx) * p[0] + fx * p[1];
    mid[r] = (1 - fx) * p[1] + fx * p[2];
    right[r] = (1 - fx) * p[2] + fx * p[3];
  }
  auto in_y = [&](const double* column, int row) { return (1 - fy) * column[row] + fy * column[row + 1]; };
  return {in_y(mid, 1), 0.5 * (in_y(right, 1) - in_y(left, 1)), 0.5 * (in_y(mid, 2) - in_y(mid, 0))};
}

inline bool Inside(const cv::Mat& image, double x, double y, double margin) {
  return x >= margin && y >= margin && x <= image.cols - 1 - margin && y <= image.rows - 1 - margin;
}

double Correlation(const std::vector<double>& a, const std::vector<double>& b) {
  const double n = static_cast<double>(a.size());
  double sa = 0, sb = 0, saa = 0, sbb = 0, sab = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    sa += a[i];
    sb += b[i];
    saa += a[i] * a[i];
    sbb += b[i] * b[i];
    sab += a[i] * b[i];
  }
  const double va = saa - sa * sa / n, vb = sbb - sb * sb / n;
  return va > 0 && vb > 0 ? (sab - sa * sb / n) / std::sqrt(va * vb) : 0.0;
}

using Vector8d = Eigen::Matrix<double, 8, 1>;
using Matrix8d = Eigen::Matrix<double, 8, 8>;

// The fit's per-patch arrays, kept for the thread's life: a triangulation
// refines hundreds of thousands of patches of the same size.
struct PatchBuffers {
  std::vector<Eigen::Vector2d> offsets;  // each patch pixel from the centre
  std::vector<double> templ, warped;     // the reference's grey values; the target's under the warp
  // One row of the Jacobian per pixel: the normal matrix is then one
  // product (vectorised by Eigen), a third of the time of summing the
  // pixels' outer products one by one.
  Eigen::Matrix<double, Eigen::Dynamic, 8> jacobian;
  Eigen::VectorXd residual;

  void Resize(size_t n) {
    offsets.resize(n);
    templ.resize(n);
    warped.resize(n);
    jacobian.resize(static_cast<Eigen::Index>(n), 8);
    residual.resize(static_cast<Eigen::Index>(n));
  }

  // The reference patch, (2 h + 1)^2 pixels round `centre`.
  void SampleTemplate(const cv::Mat& reference, const Eigen::Vector2d& centre, int h) {
    Resize(static_cast<size_t>((2 * h + 1) * (2 * h + 1)));
    for (int dy = -h, i = 0; dy <= h; ++dy) {
      for (int dx = -h; dx <= h; ++dx, ++i) {
        offsets[static_cast<size_t>(i)] = Eigen::Vector2d(dx, dy);
        templ[static_cast<size_t>(i)] = Sample(reference, centre.x() + dx, centre.y() + dy);
      }
    }
  }

  // Every other pixel of every other row of `full`'s patch (half window h),
  // over the same extent.
  void SubsampleTemplate(const PatchBuffers& full, int h) {
    const int side = h + 1, full_side = 2 * h + 1;
    Resize(static_cast<size_t>(side * side));
    for (int r = 0, i = 0; r < side; ++r) {
      for (int c = 0; c < side; ++c, ++i) {
        const size_t from = static_cast<size_t>(2 * r * full_side + 2 * c);
        offsets[static_cast<size_t>(i)] = full.offsets[from];
        templ[static_cast<size_t>(i)] = full.templ[from];
      }
    }
  }

  // Residuals and Jacobian of the target under `warp`, gain and offset
  // (parameters: centre 2, affine 4, offset, gain); false when the warped
  // patch leaves the image.
  bool Linearise(const cv::Mat& target, const PatchWarp& warp, double gain, double offset) {
    for (size_t i = 0; i < offsets.size(); ++i) {
      const Eigen::Vector2d w = warp.centre + warp.affine * offsets[i];
      // Central differences over two pixels (half the noise of the
      // bilinear patch's own slope, measured in the tests) need a pixel on
      // each side, bilinear one more.
      if (!Inside(target, w.x(), w.y(), 2)) return false;
      const SampleWithSlope at = SampleAndSlope(target, w.x(), w.y());
      const double s = at.value, gx = gain * at.gx, gy = gain * at.gy;
      warped[i] = s;
      const double x = offsets[i].x(), y = offsets[i].y();
      const Eigen::Index row = static_cast<Eigen::Index>(i);
      residual(row) = templ[i] - (gain * s + offset);
      jacobian.row(row) << gx, gy, gx * x, gx * y, gy * x, gy * y, 1.0, s;
    }
    return true;
  }

  // J^T J, formed in its lower half and mirrored.
  Matrix8d NormalMatrix() const {
    Matrix8d normal;
    for (int a = 0; a < 8; ++a) {
      for (int b = 0; b <= a; ++b) normal(a, b) = normal(b, a) = jacobian.col(a).dot(jacobian.col(b));
    }
    return normal;
  }

  // The centre's 1-sigma, px: the grey values' noise from the residuals
  // (n - 8 degrees of freedom) through the normal matrix to the centre.
  double CentreSigmaPx(const Matrix8d& normal) const {
    const double variance = residual.squaredNorm() / static_cast<double>(offsets.size() - 8);
    const Matrix8d covariance = variance * normal.inverse();
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> centre_cov(covariance.topLeftCorner<2, 2>());
    return std::sqrt(std::max(0.0, centre_cov.eigenvalues()(1)));
  }

  // The same for a centre held to a line (direction `along`): the noise
  // from the residuals (n - 7 degrees of freedom) to the position on the
  // line, and the error a shift of the line across itself by
  // `across_sigma_px` puts into it (the patch's coupling of the two
  // directions: nothing for an edge across the line, much for one
  // nearly along it).
  double LineSigmaPx(const Matrix8d& normal, const Eigen::Vector2d& along, double across_sigma_px) const {
    const Eigen::Matrix<double, 6, 6> others = normal.bottomRightCorner<6, 6>();
    const Eigen::LDLT<Eigen::Matrix<double, 6, 6>> others_ldlt(others);
    const Eigen::Matrix2d centre_info =
        normal.topLeftCorner<2, 2>() - normal.topRightCorner<2, 6>() * others_ldlt.solve(normal.bottomLeftCorner<6, 2>());
    const Eigen::Vector2d across(-along.y(), along.x());
    const double info_along = along.dot(centre_info * along);
    if (!(info_along > 0)) return std::numeric_limits<double>::infinity();
    const double coupling = along.dot(centre_info * across) / info_along;
    const double variance = residual.squaredNorm() / static_cast<double>(offsets.size() - 7);
    return std::sqrt(variance / info_along + coupling * coupling * across_sigma_px * across_sigma_px);
  }
};

void ApplyStep(const Vector8d& delta, PatchWarp* warp, double* gain, double* offset) {
  warp->centre += delta.head<2>();
  warp->affine(0, 0) += delta(2);
  warp->affine(0, 1) += delta(3);
  warp->affine(1, 0) += delta(4);
  warp->affine(1, 1) += delta(5);
  *offset += delta(6);
  *gain += delta(7);
}

}  // namespace

std::optional<PatchFit> RefinePatch(const cv::Mat& reference, const Eigen::Vector2d& reference_pixel, const cv::Mat& target,
                                    const PatchWarp& start, const PatchRefinementOptions& options,
                                    const std::optional<PatchLine>& line) {
  const int h = options.half_window;
  if (reference.type() != CV_8UC1 || target.type() != CV_8UC1) return std::nullopt;
  if (!Inside(reference, reference_pixel.x() - h, reference_pixel.y() - h, 0) ||
      !Inside(reference, reference_pixel.x() + h, reference_pixel.y() + h, 1)) {
    return std::nullopt;
  }
  thread_local PatchBuffers patch, sparse;
  patch.SampleTemplate(reference, reference_pixel, h);
  // The first steps, far from the minimum, on every other pixel (a quarter
  // of the work, the same extent and so the same reach); the last ones,
  // which locate the patch and give its sigma, on every pixel. Below a half
  // window of 4 the sparse samples would barely outnumber the 8 parameters.
  bool sparse_phase = options.sparse_until_px > 0 && h >= 4;
  if (sparse_phase) sparse.SubsampleTemplate(patch, h);
  PatchFit fit;
  fit.warp = start;
  double gain = 1, offset = 0;
  Matrix8d normal;
  bool converged = false;
  double last_step_px = 0;
  int sparse_left = sparse_phase ? options.max_iterations : 0;
  for (fit.iterations = 1; fit.iterations <= options.max_iterations;) {
    PatchBuffers& used = sparse_phase ? sparse : patch;
    if (!used.Linearise(target, fit.warp, gain, offset)) return std::nullopt;
    normal = used.NormalMatrix();
    const Vector8d gradient = used.jacobian.transpose() * used.residual;
    Vector8d delta;
    if (line) {
      // The centre moves along the line only: the step in (t, the other 6)
      // through the map P from those 7 to the 8 free parameters.
      Eigen::Matrix<double, 8, 7> p = Eigen::Matrix<double, 8, 7>::Zero();
      p.block<2, 1>(0, 0) = line->direction;
      p.bottomRightCorner<6, 6>().setIdentity();
      const Eigen::LDLT<Eigen::Matrix<double, 7, 7>> ldlt(p.transpose() * normal * p);
      if (ldlt.info() != Eigen::Success) return std::nullopt;
      delta = p * ldlt.solve(p.transpose() * gradient);
    } else {
      const Eigen::LDLT<Matrix8d> ldlt(normal);
      if (ldlt.info() != Eigen::Success) return std::nullopt;
      delta = ldlt.solve(gradient);
    }
    if (!delta.allFinite()) return std::nullopt;
    ApplyStep(delta, &fit.warp, &gain, &offset);
    // The sparse steps are noisier and may overshoot on the way; where the
    // fit ends is held to max_shift_px.
    const double reach = sparse_phase ? 2 * options.max_shift_px : options.max_shift_px;
    if ((fit.warp.centre - start.centre).norm() > reach || !(gain > 0.2 && gain < 5)) return std::nullopt;
    last_step_px = delta.head<2>().norm();
    if (sparse_phase) {
      // Sparse steps are cheap and do not use up the fit's iterations, but
      // for the one that ends them, which counts as the first.
      if (--sparse_left == 0 && !(last_step_px < options.sparse_until_px)) return std::nullopt;
      sparse_phase = !(last_step_px < options.sparse_until_px);
      if (!sparse_phase) ++fit.iterations;
      continue;
    }
    if (last_step_px < options.converged_px) {
      converged = true;
      break;
    }
    ++fit.iterations;
  }
  fit.sigma_px = line ? patch.LineSigmaPx(normal, line->direction, line->across_sigma_px) : patch.CentreSigmaPx(normal);
  if (!converged) {
    // Out of iterations: still converged if the last step was a small part
    // of the fit's own sigma from its grey values (early on, the misaligned
    // patches' residuals inflate that sigma, so the rule would stop fits too
    // soon); what that step left unresolved then counts in the sigma.
    fit.iterations = options.max_iterations;
    const double noise_sigma_px = line ? patch.LineSigmaPx(normal, line->direction, 0.0) : fit.sigma_px;
    if (!(last_step_px < options.converged_sigma_fraction * noise_sigma_px)) return std::nullopt;
    fit.sigma_px = std::hypot(fit.sigma_px, last_step_px);
  }
  fit.correlation = Correlation(patch.templ, patch.warped);
  if (!(fit.sigma_px <= options.max_sigma_px) || !(fit.correlation >= options.min_correlation)) return std::nullopt;
  return fit;
}

}  // namespace tagsfm
