#include "tagsfm/core/camera_model.h"

#include <random>

#include <gtest/gtest.h>
#include <opencv2/calib3d.hpp>

namespace tagsfm {
namespace {

CameraModel MakeCamera(std::vector<double> distortion, CameraModel::Kind kind = CameraModel::Kind::kPinhole) {
  CameraModel c;
  c.kind = kind;
  c.width = 1280;
  c.height = 720;
  c.fx = 1000;
  c.fy = 998;
  c.cx = 641.5;
  c.cy = 359.25;
  c.distortion = std::move(distortion);
  return c;
}

std::vector<Eigen::Vector3d> RandomPointsInView(int n, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> xy(-0.5, 0.5), z(1.0, 4.0);
  std::vector<Eigen::Vector3d> points;
  for (int i = 0; i < n; ++i) {
    const double depth = z(rng);
    points.emplace_back(xy(rng) * depth, xy(rng) * depth * 0.6, depth);
  }
  return points;
}

// Our hand-written projection must agree with OpenCV's for every model the
// contract allows; 1e-9 px is float64 round-off on ~1000 px coordinates.
class ProjectionAgreesWithOpenCV : public ::testing::TestWithParam<std::vector<double>> {};

TEST_P(ProjectionAgreesWithOpenCV, Pinhole) {
  const CameraModel camera = MakeCamera(GetParam());
  ASSERT_TRUE(camera.Check());
  const auto points = RandomPointsInView(200, 1);
  std::vector<cv::Point3d> object;
  for (const auto& p : points) object.emplace_back(p.x(), p.y(), p.z());
  std::vector<cv::Point2d> expected;
  cv::projectPoints(object, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), cv::Mat(camera.K()), camera.DistortionMat(), expected);
  for (size_t i = 0; i < points.size(); ++i) {
    const Eigen::Vector2d pixel = camera.Project(points[i]);
    EXPECT_NEAR(pixel.x(), expected[i].x, 1e-9);
    EXPECT_NEAR(pixel.y(), expected[i].y, 1e-9);
  }
}

INSTANTIATE_TEST_SUITE_P(DistortionModels, ProjectionAgreesWithOpenCV,
                         ::testing::Values(std::vector<double>{}, std::vector<double>{-0.2, 0.05, 0.001, -0.0005},
                                           std::vector<double>{-0.2, 0.05, 0.001, -0.0005, 0.01},
                                           std::vector<double>{-0.2, 0.05, 0.001, -0.0005, 0.01, 0.02, -0.01, 0.003},
                                           std::vector<double>{-0.2, 0.05, 0.001, -0.0005, 0.01, 0.02, -0.01, 0.003,
                                                               0.001, -0.002, 0.0005, 0.0007}));

TEST(CameraModel, FisheyeProjectionAgreesWithOpenCV) {
  const CameraModel camera = MakeCamera({0.05, -0.01, 0.002, -0.0003}, CameraModel::Kind::kFisheye);
  ASSERT_TRUE(camera.Check());
  const auto points = RandomPointsInView(100, 2);
  std::vector<cv::Point3d> object;
  for (const auto& p : points) object.emplace_back(p.x(), p.y(), p.z());
  std::vector<cv::Point2d> expected;
  cv::fisheye::projectPoints(object, expected, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), cv::Mat(camera.K()),
                             camera.DistortionMat());
  for (size_t i = 0; i < points.size(); ++i) {
    const Eigen::Vector2d pixel = camera.Project(points[i]);
    EXPECT_NEAR(pixel.x(), expected[i].x, 1e-8);
    EXPECT_NEAR(pixel.y(), expected[i].y, 1e-8);
  }
}

// Undistortion is iterative; corner accuracy is judged at ~0.01 px, so the
// round trip must be far below that: 1e-6 px.
TEST(CameraModel, PixelToNormalizedInvertsProject) {
  for (const auto& distortion : {std::vector<double>{}, std::vector<double>{-0.25, 0.08, 0.001, -0.0005, -0.01}}) {
    const CameraModel camera = MakeCamera(distortion);
    const auto points = RandomPointsInView(100, 3);
    std::vector<Eigen::Vector2d> pixels;
    for (const auto& p : points) pixels.push_back(camera.Project(p));
    const auto normalized = camera.PixelsToNormalized(pixels);
    for (size_t i = 0; i < points.size(); ++i) {
      const Eigen::Vector3d back(normalized[i].x(), normalized[i].y(), 1.0);
      EXPECT_LT((camera.Project(back) - pixels[i]).norm(), 1e-6);
    }
  }
}

TEST(CameraModel, CheckNamesTheWrongField) {
  CameraModel camera = MakeCamera({});
  camera.fx = -3;
  Status s = camera.Check();
  ASSERT_FALSE(s);
  EXPECT_NE(s.error().message.find("camera.fx"), std::string::npos) << s.error().message;
  camera = MakeCamera({0.1, 0.2, 0.3});
  s = camera.Check();
  ASSERT_FALSE(s);
  EXPECT_NE(s.error().message.find("camera.distortion"), std::string::npos) << s.error().message;
  camera = MakeCamera({0.1, 0.2, 0.3, 0.4, 0.5}, CameraModel::Kind::kFisheye);
  EXPECT_FALSE(camera.Check());
  camera = MakeCamera({});
  camera.width = 0;
  EXPECT_FALSE(camera.Check());
}

}  // namespace
}  // namespace tagsfm
