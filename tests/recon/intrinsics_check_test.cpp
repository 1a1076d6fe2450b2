// Judging adjusted intrinsics by their covariance (recon/intrinsics_check.h).
#include <cmath>

#include <gtest/gtest.h>

#include "tagsfm/recon/intrinsics_check.h"
#include "test_camera.h"

namespace tagsfm {
namespace {

CameraModel Camera() { return testing::PinholeCamera(1280, 720, 1000, 639.5, 359.5); }

// The distortion's sigma at a radius is the (k1, k2) covariance carried
// through r_px (k1 r^2 + k2 r^4): with k1 alone it is r_px r^2 sigma_k1, and
// a perfect anticorrelation of k1 and k2 cancels where their terms are equal.
TEST(IntrinsicsCheck, DistortionSigmaFollowsTheRadiusAndTheCorrelation) {
  const CameraModel camera = Camera();
  Eigen::Matrix<double, 6, 6> cov = Eigen::Matrix<double, 6, 6>::Zero();
  cov(4, 4) = 1e-6;  // sigma k1 0.001
  EXPECT_NEAR(DistortionSigmaAtRadiusPx(camera, cov, 500), 500 * 0.25 * 1e-3, 1e-12);
  EXPECT_NEAR(CornerRadiusPx(camera), std::hypot(640.0, 360.0), 1e-9);
  cov(5, 5) = 16e-6;  // sigma k2 0.004, k2 = -4 k1 in every sample: r^2 = 1/4 cancels
  cov(4, 5) = cov(5, 4) = -4e-6;
  EXPECT_NEAR(DistortionSigmaAtRadiusPx(camera, cov, 500), 0.0, 1e-9);
  EXPECT_GT(DistortionSigmaAtRadiusPx(camera, cov, 700), 0.01);
}

TEST(IntrinsicsCheck, NamesEachParameterBeyondItsLimit) {
  const CameraModel camera = Camera();
  Eigen::Matrix<double, 6, 6> cov = Eigen::Matrix<double, 6, 6>::Identity() * 1e-8;
  cov(0, 0) = cov(1, 1) = 0.3 * 0.3;  // 0.03 %: constrained
  cov(2, 2) = cov(3, 3) = 0.2 * 0.2;
  const IntrinsicsCheckOptions options;
  EXPECT_TRUE(UnconstrainedIntrinsics(camera, cov, 400, options).empty());
  cov(1, 1) = 3.0 * 3.0;  // fy 0.3 %
  cov(2, 2) = 2.5 * 2.5;  // cx 2.5 px
  const auto weak = UnconstrainedIntrinsics(camera, cov, 400, options);
  ASSERT_EQ(weak.size(), 2u);
  EXPECT_EQ(weak[0].rfind("fy: sigma 3.00 px", 0), 0u) << weak[0];
  EXPECT_EQ(weak[1].rfind("cx: sigma 2.50 px", 0), 0u) << weak[1];
  cov(4, 4) = 0.02 * 0.02;  // k1 known to 0.02: 1.28 px 400 px from the centre
  EXPECT_EQ(UnconstrainedIntrinsics(camera, cov, 400, options).size(), 3u);
  EXPECT_EQ(UnconstrainedIntrinsics(camera, cov, 100, options).size(), 2u);  // 0.02 px at 100 px

  IntrinsicsCheckOptions bad;
  bad.max_principal_point_sigma_px = 0;
  const Status s = bad.Check();
  ASSERT_FALSE(s);
  EXPECT_NE(s.error().message.find("max_principal_point_sigma_px"), std::string::npos);
}

}  // namespace
}  // namespace tagsfm
