// Feature triangulation from known poses against exact synthetic geometry.
#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "tagsfm/feature/feature_triangulation.h"
#include "test_camera.h"

namespace tagsfm {
namespace {

CameraModel TestCamera() { return testing::PinholeCamera(1280, 720, 1000, 640, 360); }

// Cameras on an arc 2 m from the origin, looking at it, `spread_deg` apart.
std::vector<Rigid3d> ArcCameras(int count, double spread_deg) {
  std::vector<Rigid3d> cams;
  for (int i = 0; i < count; ++i) {
    const double a = (i - (count - 1) / 2.0) * spread_deg * M_PI / 180.0;
    const Eigen::Vector3d centre(2.0 * std::sin(a), 0.1, -2.0 * std::cos(a));
    const Eigen::Vector3d z = (-centre).normalized();
    const Eigen::Vector3d x = Eigen::Vector3d::UnitY().cross(z).normalized();
    const Eigen::Vector3d y = z.cross(x);
    Eigen::Matrix3d r;
    r.row(0) = x;
    r.row(1) = y;
    r.row(2) = z;
    cams.emplace_back(Eigen::Quaterniond(r), -(r * centre));
  }
  return cams;
}

std::vector<FeatureRay> Rays(const std::vector<Rigid3d>& cams, const Eigen::Vector3d& point) {
  std::vector<FeatureRay> rays;
  for (const Rigid3d& c : cams) rays.push_back({c, (c * point).normalized()});
  return rays;
}

TEST(FeatureTriangulation, ExactRaysGiveTheExactPoint) {
  const auto cams = ArcCameras(4, 10.0);
  const Eigen::Vector3d point(0.3, -0.2, 0.25);
  const auto linear = TriangulateLinear(Rays(cams, point));
  ASSERT_TRUE(linear.has_value());
  EXPECT_LT((*linear - point).norm(), 1e-9);
  EXPECT_LT((RefineAngularError(Rays(cams, point), *linear + Eigen::Vector3d(0.01, -0.02, 0.03), 10) - point).norm(), 1e-9);
}

// A ray known to be ten times worse located (weight 1/100) pulls the point
// far less than the others: the weighted least squares follows the good rays.
TEST(FeatureTriangulation, AWorseRayWeighsLess) {
  const auto cams = ArcCameras(4, 10.0);
  const Eigen::Vector3d point(0.3, -0.2, 0.25);
  std::vector<FeatureRay> rays = Rays(cams, point);
  // 2 px off in the image (f = 1000 px): 2 mrad across the first ray.
  rays[0].bearing = (rays[0].bearing + 2e-3 * rays[0].bearing.unitOrthogonal()).normalized();
  const Eigen::Vector3d alike = RefineAngularError(rays, point, 10);
  rays[0].weight = 0.01;
  const Eigen::Vector3d weighted = RefineAngularError(rays, point, 10);
  std::printf("error: %.3f mm alike, %.3f mm weighted\n", 1e3 * (alike - point).norm(), 1e3 * (weighted - point).norm());
  EXPECT_GT((alike - point).norm(), 1e-3);
  EXPECT_LT((weighted - point).norm(), 0.05 * (alike - point).norm());
  // The normal matrix scales with the weights.
  for (FeatureRay& r : rays) r.weight = 0.25;
  std::vector<FeatureRay> unit = rays;
  for (FeatureRay& r : unit) r.weight = 1.0;
  EXPECT_LT((AngularNormalMatrix(rays, point) - 0.25 * AngularNormalMatrix(unit, point)).norm(),
            1e-12 * AngularNormalMatrix(unit, point).norm());
}

TEST(FeatureTriangulation, ParallelRaysHaveNoPoint) {
  std::vector<Rigid3d> cams{Rigid3d(), Rigid3d()};
  const Eigen::Vector3d bearing = Eigen::Vector3d(0.1, 0.2, 1.0).normalized();
  EXPECT_FALSE(TriangulateLinear({{cams[0], bearing}, {cams[1], bearing}}).has_value());
}

// With 0.3 px noise the angular refinement must not be worse than the
// linear start (it is the maximum-likelihood estimate for isotropic ray
// noise, the DLT is not), and the error must be what the geometry allows:
// at 2 m, 1000 px focal length and 10 degrees between neighbouring rays
// (40 over the arc), 0.3 px gives about 2 * 0.3/1000 / sin(20 deg) ~ 2 mm
// along the depth at worst; 3 mm RMS is a safe bound.
TEST(FeatureTriangulation, AngularRefinementIsNoWorseThanLinearUnderNoise) {
  const auto cams = ArcCameras(5, 10.0);
  const CameraModel camera = TestCamera();
  std::mt19937 rng(3);
  std::normal_distribution<double> noise(0.0, 0.3);
  std::uniform_real_distribution<double> coord(-0.4, 0.4);
  double linear_sq = 0, refined_sq = 0, mahalanobis = 0;
  const int n = 300;
  for (int k = 0; k < n; ++k) {
    const Eigen::Vector3d point(coord(rng), coord(rng), coord(rng));
    std::vector<FeatureRay> rays;
    for (const Rigid3d& c : cams) {
      const Eigen::Vector2d pixel = camera.Project(c * point) + Eigen::Vector2d(noise(rng), noise(rng));
      rays.push_back({c, camera.PixelToNormalized(pixel).homogeneous().normalized()});
    }
    const auto linear = TriangulateLinear(rays);
    ASSERT_TRUE(linear.has_value());
    linear_sq += (*linear - point).squaredNorm();
    const Eigen::Vector3d refined = RefineAngularError(rays, *linear, 10);
    refined_sq += (refined - point).squaredNorm();
    const double sigma = 0.3 / camera.fx;
    const Eigen::Matrix3d covariance = sigma * sigma * AngularNormalMatrix(rays, refined).inverse();
    mahalanobis += (refined - point).dot(covariance.inverse() * (refined - point));
  }
  // The covariance from the normal matrix explains the errors: the mean
  // squared Mahalanobis distance is chi-square with 3 dof, mean 3; over 300
  // draws its standard deviation is sqrt(6/300) = 0.14, so [2.5, 3.5] is a
  // bound at more than 3 sigma.
  EXPECT_GT(mahalanobis / n, 2.5);
  EXPECT_LT(mahalanobis / n, 3.5);
  const double linear_rms = std::sqrt(linear_sq / n), refined_rms = std::sqrt(refined_sq / n);
  EXPECT_LE(refined_rms, linear_rms * 1.001) << "linear " << linear_rms << " refined " << refined_rms;
  EXPECT_LT(refined_rms, 0.003);
  EXPECT_GT(refined_rms, 0.0001);  // the noise is really there
}

TEST(FeatureTriangulation, TracksAreFilteredByLengthAngleAndReprojection) {
  const CameraModel camera = TestCamera();
  const auto cams = ArcCameras(4, 8.0);
  PoseMap poses;
  for (size_t i = 0; i < cams.size(); ++i) poses[static_cast<FrameId>(i)] = cams[i];
  const Eigen::Vector3d good(0.1, 0.1, 0.0), short_track(-0.1, 0.2, 0.1), outlier(0.2, -0.1, 0.1);
  std::vector<FeatureSet> sets(cams.size());
  for (size_t i = 0; i < cams.size(); ++i) {
    sets[i].frame = static_cast<FrameId>(i);
    sets[i].features.push_back({1, camera.Project(cams[i] * good), {10, 20, 30}});
    if (i < 2) sets[i].features.push_back({2, camera.Project(cams[i] * short_track), {}});
    // Track 3: one view 6 px off (a wrong match), beyond max_reprojection_px.
    sets[i].features.push_back({3, camera.Project(cams[i] * outlier) + Eigen::Vector2d(i == 2 ? 6.0 : 0.0, 0.0), {}});
  }
  // Frame 9 is not registered: its observation must be ignored.
  sets.push_back({9, {{1, Eigen::Vector2d(5, 5), {}}}, 0});
  FeatureTriangulationOptions options;
  const auto points = TriangulateFeatureTracks(sets, poses, camera, options);
  ASSERT_EQ(points.size(), 1u);
  EXPECT_EQ(points[0].track, 1);
  EXPECT_LT((points[0].position - good).norm(), 1e-9);
  EXPECT_EQ(points[0].observations.size(), 4u);
  EXPECT_NEAR(points[0].max_angle_deg, 24.0, 3.0);  // 3 steps of 8 degrees, seen from 2 m

  // Rays narrower than min_angle_deg: no point.
  options.min_angle_deg = 40.0;
  EXPECT_TRUE(TriangulateFeatureTracks(sets, poses, camera, options).empty());
}

TEST(FeatureTriangulation, OptionsCheckNamesTheField) {
  FeatureTriangulationOptions options;
  options.min_angle_deg = 0;
  const Status s = options.Check();
  ASSERT_FALSE(s);
  EXPECT_NE(s.error().message.find("min_angle_deg"), std::string::npos);
}

}  // namespace
}  // namespace tagsfm
