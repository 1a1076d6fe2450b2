// The two-view and PnP stages, and triangulation, against exact synthetic
// correspondences (and outliers): what the mapper is built on.
#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "tagsfm/sfm/geometry.h"
#include "tagsfm/sfm/two_view.h"
#include "look_at.h"

namespace tagsfm::sfm {
namespace {

Rigid3d LookingAtOrigin(const Eigen::Vector3d& centre) { return LookingAt(centre, Eigen::Vector3d::Zero()); }

std::vector<Eigen::Vector3d> PointsInBox(int n, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-0.5, 0.5);
  std::vector<Eigen::Vector3d> points;
  for (int i = 0; i < n; ++i) points.emplace_back(u(rng), u(rng), u(rng));
  return points;
}

Eigen::Vector2d Normalized(const Rigid3d& cam_from_world, const Eigen::Vector3d& x) {
  const Eigen::Vector3d p = cam_from_world * x;
  return p.head<2>() / p.z();
}

TEST(SfmRelativePose, ExactCorrespondencesGiveTheTruePose) {
  const Rigid3d a = LookingAtOrigin({0, -0.2, -2.0});
  const Rigid3d b = LookingAtOrigin({0.6, -0.1, -1.9});
  const std::vector<Eigen::Vector3d> points = PointsInBox(300, 1);
  std::vector<Eigen::Vector2d> na, nb;
  for (const auto& x : points) {
    na.push_back(Normalized(a, x));
    nb.push_back(Normalized(b, x));
  }
  // 120 of the 300 matches wrong (60 swapped pairs), more than the ratio test lets through.
  for (size_t i = 0; i < 60; ++i) std::swap(nb[i], nb[i + 100]);
  RelativePoseOptions options;
  auto pose = EstimateRelativePose(na, nb, options);
  ASSERT_TRUE(pose.has_value()) << pose.error().message;
  const Rigid3d truth = b * a.Inverse();
  EXPECT_LT(RotationAngleDeg(pose->cam_b_from_cam_a.rotation, truth.rotation), 1e-6);
  const double direction = std::acos(std::clamp(pose->cam_b_from_cam_a.translation.dot(truth.translation.normalized()), -1.0, 1.0));
  EXPECT_LT(direction * 180 / M_PI, 1e-5);
  // Every true pair, and of the 120 swapped ones only those that happen to
  // fall within 4 px of their epipolar line.
  EXPECT_GE(pose->inliers.size(), 180u);
  EXPECT_LE(pose->inliers.size(), 200u);
  // The baseline (0.6 m at 2 m) sees the points at 14-20 degrees.
  EXPECT_GT(pose->median_angle_deg, 10);
  EXPECT_LT(pose->median_angle_deg, 25);
}

TEST(SfmRelativePose, TooFewOrPureRotationIsAnErrorOrNarrow) {
  const Rigid3d a = LookingAtOrigin({0, -0.2, -2.0});
  const std::vector<Eigen::Vector3d> points = PointsInBox(100, 2);
  std::vector<Eigen::Vector2d> na, nb;
  // The same centre, turned by 5 degrees: no baseline to triangulate from.
  const Rigid3d b(Eigen::Quaterniond(Eigen::AngleAxisd(0.087, Eigen::Vector3d::UnitY())) * a.rotation,
                  Eigen::Quaterniond(Eigen::AngleAxisd(0.087, Eigen::Vector3d::UnitY())) * a.translation);
  for (const auto& x : points) {
    na.push_back(Normalized(a, x));
    nb.push_back(Normalized(b, x));
  }
  auto pose = EstimateRelativePose(na, nb, {});
  if (pose) {
    EXPECT_LT(pose->median_angle_deg, 0.5);
  }
  na.resize(10);
  nb.resize(10);
  auto few = EstimateRelativePose(na, nb, {});
  ASSERT_FALSE(few.has_value());
  EXPECT_NE(few.error().message.find("fewer than"), std::string::npos);
}

TEST(SfmAbsolutePose, ExactCorrespondencesWithOutliersGiveTheTruePose) {
  const Rigid3d truth = LookingAtOrigin({0.8, -0.3, -1.7});
  const std::vector<Eigen::Vector3d> points = PointsInBox(200, 3);
  std::vector<Eigen::Vector2d> image;
  for (const auto& x : points) image.push_back(Normalized(truth, x));
  for (size_t i = 0; i < 50; ++i) image[i] += Eigen::Vector2d(0.05, -0.04);  // 50 px off at f = 1000
  auto pose = EstimateAbsolutePose(points, image, {});
  ASSERT_TRUE(pose.has_value()) << pose.error().message;
  EXPECT_LT(RotationAngleDeg(pose->cam_from_world.rotation, truth.rotation), 1e-6);
  EXPECT_LT((pose->cam_from_world.Center() - truth.Center()).norm(), 1e-8);
  EXPECT_EQ(pose->inliers.size(), 150u);
  image.resize(20);
  auto points20 = points;
  points20.resize(20);
  EXPECT_FALSE(EstimateAbsolutePose(points20, image, {}).has_value());
}

TEST(SfmTriangulation, ExactViewsGiveThePointAndItsAngle) {
  const Eigen::Vector3d x(0.1, -0.2, 0.3);
  std::vector<View> views;
  for (const Eigen::Vector3d& c : {Eigen::Vector3d(0, 0, -2), Eigen::Vector3d(1, 0, -2), Eigen::Vector3d(-1, 0.5, -2)}) {
    const Rigid3d pose = LookingAtOrigin(c);
    views.push_back({pose, Normalized(pose, x)});
  }
  auto point = TriangulateViews(views);
  ASSERT_TRUE(point.has_value());
  EXPECT_LT((*point - x).norm(), 1e-9);
  for (const View& v : views) EXPECT_LT(ReprojectionError(v, *point), 1e-12);
  // Rays from (1,0,-2) and (-1,0.5,-2) meet at about 55 degrees.
  const double angle = MaxTriangulationAngleDeg(views, x);
  EXPECT_GT(angle, 45);
  EXPECT_LT(angle, 65);
  // Behind the camera: infinite error, so cheirality checks reject it.
  EXPECT_TRUE(std::isinf(ReprojectionError(views[0], Eigen::Vector3d(0, 0, -5))));
}

}  // namespace
}  // namespace tagsfm::sfm
