// Each residual's automatic derivatives against numeric ones.
#include "tagsfm/recon/cost_functions.h"

#include <algorithm>
#include <cmath>

#include <gtest/gtest.h>

#include "tagsfm/recon/pose_params.h"
#include "tagsfm/recon/tag_geometry.h"

namespace tagsfm {
namespace {

PoseParams SomePose(double ax, double ay, double az, const Eigen::Vector3d& t) {
  const Eigen::Quaterniond q = Eigen::AngleAxisd(ax, Eigen::Vector3d::UnitX()) *
                               Eigen::AngleAxisd(ay, Eigen::Vector3d::UnitY()) *
                               Eigen::AngleAxisd(az, Eigen::Vector3d::UnitZ());
  return PoseParams(Rigid3d(q, t));
}

// Automatic derivatives (CostFunction::Evaluate) against central
// differences in the ambient parameters, with plain arrays only (Ceres'
// GradientChecker passes Eigen objects across the library boundary, which
// the sanitizer build does not survive). Relative precision 1e-6 is what
// central differences with h = 1e-6 reach on these smooth residuals.
void ExpectDerivativesMatch(ceres::CostFunction* cost, std::vector<const ceres::Manifold*> /*manifolds*/,
                            std::vector<double*> blocks, double precision = 1e-6) {
  const int m = cost->num_residuals();
  const auto& sizes = cost->parameter_block_sizes();
  std::vector<std::vector<double>> jacobians(sizes.size());
  std::vector<double*> jacobian_ptrs;
  for (size_t b = 0; b < sizes.size(); ++b) {
    jacobians[b].resize(static_cast<size_t>(m * sizes[b]));
    jacobian_ptrs.push_back(jacobians[b].data());
  }
  std::vector<double> residuals(static_cast<size_t>(m)), plus(residuals), minus(residuals);
  ASSERT_TRUE(cost->Evaluate(blocks.data(), residuals.data(), jacobian_ptrs.data()));
  for (size_t b = 0; b < sizes.size(); ++b) {
    for (int j = 0; j < sizes[b]; ++j) {
      const double saved = blocks[b][j];
      const double h = 1e-6 * std::max(1.0, std::abs(saved));
      blocks[b][j] = saved + h;
      ASSERT_TRUE(cost->Evaluate(blocks.data(), plus.data(), nullptr));
      blocks[b][j] = saved - h;
      ASSERT_TRUE(cost->Evaluate(blocks.data(), minus.data(), nullptr));
      blocks[b][j] = saved;
      for (int r = 0; r < m; ++r) {
        const double numeric = (plus[r] - minus[r]) / (2 * h);
        const double automatic = jacobians[b][static_cast<size_t>(r * sizes[b] + j)];
        EXPECT_NEAR(automatic, numeric, precision * std::max(1.0, std::abs(numeric)))
            << "block " << b << " parameter " << j << " residual " << r;
      }
    }
  }
  delete cost;
}

TEST(CostFunctions, ReprojectionErrorDerivatives) {
  PoseParams cam = SomePose(0.1, -0.2, 0.3, {0.1, -0.05, 2.0});
  double point[3] = {0.2, -0.1, 0.3};
  ExpectDerivativesMatch(ReprojectionError::Create({0.05, -0.02}, 1000, 1001), {nullptr, nullptr},
                         {cam.data, point});
}

TEST(CostFunctions, FixedPointReprojectionErrorDerivatives) {
  PoseParams cam = SomePose(-0.3, 0.2, 0.1, {0.0, 0.1, 1.5});
  ExpectDerivativesMatch(FixedPointReprojectionError::Create({0.01, 0.02}, {0.1, 0.2, 0.3}, 900, 900),
                         {nullptr}, {cam.data});
}

TEST(CostFunctions, TagCornerReprojectionErrorDerivatives) {
  PoseParams cam = SomePose(0.2, 0.1, -0.1, {0.05, 0.0, 2.5});
  PoseParams tag = SomePose(1.2, 0.3, 0.4, {0.3, -0.2, 0.5});
  ExpectDerivativesMatch(TagCornerReprojectionError::Create({0.1, 0.05}, {0.03, -0.03, 0}, 1000, 1000),
                         {nullptr, nullptr}, {cam.data, tag.data});
}

TEST(CostFunctions, TagReprojectionErrorDerivativesAndAgreementWithPerCorner) {
  PoseParams cam = SomePose(0.2, 0.1, -0.1, {0.05, 0.0, 2.5});
  PoseParams tag = SomePose(1.2, 0.3, 0.4, {0.3, -0.2, 0.5});
  const std::array<Eigen::Vector2d, 4> observed{Eigen::Vector2d(0.1, 0.05), Eigen::Vector2d(0.12, 0.05),
                                                Eigen::Vector2d(0.12, 0.07), Eigen::Vector2d(0.1, 0.07)};
  ExpectDerivativesMatch(TagReprojectionError::Create(observed, 0.06, 1000, 990),
                         {nullptr, nullptr}, {cam.data, tag.data});
  // The four-corner block equals the four per-corner residuals.
  double block[8];
  ASSERT_TRUE(TagReprojectionError(observed, 0.06, 1000, 990)(cam.data, tag.data, block));
  for (int k = 0; k < 4; ++k) {
    double corner[2];
    ASSERT_TRUE(TagCornerReprojectionError(observed[k], TagCornerInTag(k, 0.06), 1000, 990)(cam.data, tag.data, corner));
    EXPECT_NEAR(block[2 * k], corner[0], 1e-9);
    EXPECT_NEAR(block[2 * k + 1], corner[1], 1e-9);
  }
  // Each corner's weight (corner_weights.h) multiplies its residual.
  std::array<Eigen::Matrix2d, 4> weights;
  for (int k = 0; k < 4; ++k) weights[k] << 1.5 + k, 0.3, -0.2, 0.7;
  ExpectDerivativesMatch(TagReprojectionError::Create(observed, 0.06, 1000, 990, weights), {nullptr, nullptr},
                         {cam.data, tag.data});
  double weighted[8];
  ASSERT_TRUE(TagReprojectionError(observed, 0.06, 1000, 990, weights)(cam.data, tag.data, weighted));
  for (int k = 0; k < 4; ++k) {
    const Eigen::Vector2d expected = weights[k] * Eigen::Vector2d(block[2 * k], block[2 * k + 1]);
    EXPECT_NEAR(weighted[2 * k], expected.x(), 1e-9);
    EXPECT_NEAR(weighted[2 * k + 1], expected.y(), 1e-9);
  }
}

// A pose block's tangent is [rotation (3), translation (3)], the rotation
// applied on the left (world frame): the order targets_cov.csv documents.
TEST(CostFunctions, PoseManifoldTangentIsRotationThenTranslation) {
  const PoseManifold manifold;
  ASSERT_EQ(manifold.AmbientSize(), 7);
  ASSERT_EQ(manifold.TangentSize(), 6);
  PoseParams pose = SomePose(0.3, -0.2, 0.1, {0.1, 0.2, 0.3});
  const double delta[6] = {0.01, -0.02, 0.03, 0.4, 0.5, 0.6};
  PoseParams moved;
  ASSERT_TRUE(manifold.Plus(pose.data, delta, moved.data));
  const Rigid3d before = pose.ToRigid(), after = moved.ToRigid();
  EXPECT_NEAR((after.translation - before.translation - Eigen::Vector3d(0.4, 0.5, 0.6)).norm(), 0, 1e-12);
  // EigenQuaternionManifold: q' = exp(delta) * q, exp(delta) = (sin|d| d/|d|, cos|d|).
  const Eigen::Vector3d d(0.01, -0.02, 0.03);
  const Eigen::Quaterniond left(Eigen::AngleAxisd(2 * d.norm(), d.normalized()));
  EXPECT_LT(left.angularDistance(after.rotation * before.rotation.inverse()), 1e-12);
}

TEST(CostFunctions, TagEdgeLengthErrorDerivativesAndValue) {
  double a[3] = {0.2, 0.1, 0.3}, b[3] = {0.261, 0.101, 0.3};
  // The numeric derivative of this steep residual (1/sigma = 1e4) is 1.2e-5
  // off in relative terms; the analytic one, -(dx/|d|)/sigma = -9998.66, is
  // the exact value, so the check allows 1e-4 here.
  ExpectDerivativesMatch(TagEdgeLengthError::Create(0.06, 1e-4), {nullptr, nullptr}, {a, b}, 1e-4);
  const TagEdgeLengthError error(0.06, 1e-4);
  double residual = 0;
  ASSERT_TRUE(error(a, b, &residual));
  // |b - a| = sqrt(0.061^2 + 0.001^2) = 0.0610082; (0.0610082 - 0.06) / 1e-4 = 10.082.
  EXPECT_NEAR(residual, 10.082, 1e-3);
}

TEST(CostFunctions, SquarePixelTieDerivativesAndValue) {
  double intrinsics[6] = {1000.2, 999.9, 640, 360, -0.05, 0.01};
  ExpectDerivativesMatch(SquarePixelTie::Create(1e-3), {nullptr}, {intrinsics}, 1e-4);
  double residual = 0;
  ASSERT_TRUE(SquarePixelTie(1e-3)(intrinsics, &residual));
  EXPECT_NEAR(residual, 300.0, 1e-6);  // 0.3 px over 1e-3
}

TEST(CostFunctions, ReprojectionErrorIsZeroAtTheTruthAndReadsInPixels) {
  PoseParams cam = SomePose(0.1, 0.2, 0.0, {0.0, 0.0, 2.0});
  double point[3] = {0.1, 0.2, 0.3};
  const Eigen::Vector3d in_cam = cam.ToRigid() * Eigen::Vector3d(point[0], point[1], point[2]);
  const Eigen::Vector2d observed(in_cam.x() / in_cam.z(), in_cam.y() / in_cam.z());
  double residual[2];
  ASSERT_TRUE(ReprojectionError(observed, 1000, 800)(cam.data, point, residual));
  EXPECT_NEAR(residual[0], 0, 1e-9);
  EXPECT_NEAR(residual[1], 0, 1e-9);
  // An observation 0.001 off in normalised x is 1 px at fx = 1000.
  ASSERT_TRUE(ReprojectionError(observed + Eigen::Vector2d(0.001, 0.001), 1000, 800)(cam.data, point, residual));
  EXPECT_NEAR(residual[0], -1.0, 1e-9);
  EXPECT_NEAR(residual[1], -0.8, 1e-9);
}

}  // namespace
}  // namespace tagsfm
