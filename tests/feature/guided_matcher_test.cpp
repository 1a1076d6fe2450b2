// Guided matching against true correspondences: features of a textured
// plane seen from two known poses, rendered by warping one image with the
// plane's exact homography, so every feature's true partner is known.
#include <cmath>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "tagsfm/feature/guided_matcher.h"

namespace tagsfm {
namespace {

CameraModel TestCamera() {
  CameraModel c;
  c.width = 960;
  c.height = 720;
  c.fx = c.fy = 800;
  c.cx = 479.5;
  c.cy = 359.5;
  return c;
}

cv::Mat Texture(int width, int height, unsigned seed) {
  cv::Mat noise(height, width, CV_32F);
  cv::RNG rng(seed);
  rng.fill(noise, cv::RNG::NORMAL, 0.0, 1.0);
  cv::Mat smooth, out;
  cv::GaussianBlur(noise, smooth, cv::Size(0, 0), 2.5);
  cv::normalize(smooth, out, 20, 235, cv::NORM_MINMAX, CV_8U);
  return out;
}

// Camera `angle_deg` about the plane z = depth's centre, looking at it.
Rigid3d CameraAt(double angle_deg, double depth) {
  const double a = angle_deg * M_PI / 180.0;
  const Eigen::Vector3d centre(depth * std::sin(a), 0, depth - depth * std::cos(a));
  const Eigen::Matrix3d world_from_cam = Eigen::AngleAxisd(-a, Eigen::Vector3d::UnitY()).toRotationMatrix();
  const Eigen::Matrix3d r = world_from_cam.transpose();
  return Rigid3d(Eigen::Quaterniond(r), -(r * centre));
}

// Homography taking pixels of camera `a` to camera `b` for the plane z = depth.
cv::Matx33d PlaneHomography(const CameraModel& c, const Rigid3d& a, const Rigid3d& b, double depth) {
  const Rigid3d b_from_a = b * a.Inverse();
  // The plane in a's frame: n^T X = d.
  const Eigen::Vector3d n = a.rotation * Eigen::Vector3d::UnitZ();
  const double d = n.dot(a * Eigen::Vector3d(0, 0, depth));
  const Eigen::Matrix3d k = (Eigen::Matrix3d() << c.fx, 0, c.cx, 0, c.fy, c.cy, 0, 0, 1).finished();
  const Eigen::Matrix3d h = k * (b_from_a.RotationMatrix() + b_from_a.translation * n.transpose() / d) * k.inverse();
  cv::Matx33d out;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) out(i, j) = h(i, j);
  return out;
}

Eigen::Vector2d Apply(const cv::Matx33d& h, const Eigen::Vector2d& p) {
  const cv::Vec3d q = h * cv::Vec3d(p.x(), p.y(), 1.0);
  return Eigen::Vector2d(q[0] / q[2], q[1] / q[2]);
}

struct Scored {
  int matches = 0;
  int within_1px = 0;  // of the true partner's position
  // Within 3 px: SIFT localises to 1-3 px under 15-30 degrees of
  // foreshortening; a wrong match lies anywhere on the segment.
  int correct = 0;
  long long candidates = 0;
  double pairs = 0;  // features of the first times features of the second
};

Scored MatchPlaneViews(double angle_deg, const GuidedMatcherOptions& options, const Rigid3d& pose_error = Rigid3d()) {
  const CameraModel camera = TestCamera();
  const double depth = 2.0;
  const Rigid3d a = CameraAt(0, depth), b = CameraAt(angle_deg, depth);
  const cv::Mat first = Texture(camera.width, camera.height, 11);
  const cv::Matx33d h = PlaneHomography(camera, a, b, depth);
  cv::Mat second;
  cv::warpPerspective(first, second, cv::Mat(h), first.size(), cv::INTER_CUBIC, cv::BORDER_CONSTANT, cv::Scalar(128));
  FeatureExtractorOptions extractor;
  auto fa = ExtractFeatures(first, cv::Mat(), DetectionSet{0, {}}, extractor);
  auto fb = ExtractFeatures(second, cv::Mat(), DetectionSet{1, {}}, extractor);
  EXPECT_TRUE(fa && fb);
  const DepthRange range = DepthRange::Around(depth, 2.0);
  auto ka = MakePosedKeyframe(*fa, a, range, camera);
  auto kb = MakePosedKeyframe(*fb, pose_error * b, range, camera);
  EXPECT_TRUE(ka && kb);
  const GuidedMatches m = MatchGuided(*ka, *kb, camera, options);
  Scored s;
  s.candidates = m.candidates;
  s.pairs = double(ka->features.size()) * kb->features.size();
  for (const FeatureMatch& match : m.matches) {
    ++s.matches;
    const Eigen::Vector2d truth = Apply(h, ka->features.pixels[static_cast<size_t>(match.first)]);
    const double e = (kb->features.pixels[static_cast<size_t>(match.second)] - truth).norm();
    s.within_1px += e < 1.0;
    s.correct += e < 3.0;
  }
  return s;
}

// Nearly every guided match is a true correspondence, and there are many:
// the plane's texture has ~7,000 SIFT features per view.
TEST(GuidedMatcher, MatchesAreTrueCorrespondences) {
  for (double angle : {5.0, 15.0, 30.0}) {
    const Scored s = MatchPlaneViews(angle, {});
    EXPECT_GE(s.matches, angle < 20 ? 3000 : 1500) << angle << " deg";
    EXPECT_GE(s.correct, 0.995 * s.matches) << angle << " deg: " << s.correct << " of " << s.matches;
    EXPECT_GE(s.within_1px, 0.95 * s.matches) << angle << " deg: " << s.within_1px << " of " << s.matches;
    // Few candidates per feature: the segment search, not a brute force.
    EXPECT_LT(s.candidates, 0.01 * s.pairs) << angle << " deg";
  }
}

// A pose off by far more than the band (1 degree: ~14 px at 800 px focal
// length) leaves almost no match: the poses really constrain the search.
TEST(GuidedMatcher, AWrongPoseFindsAlmostNothing) {
  const Rigid3d off(Eigen::Quaterniond(Eigen::AngleAxisd(1.0 * M_PI / 180.0, Eigen::Vector3d::UnitX())), Eigen::Vector3d::Zero());
  const Scored right = MatchPlaneViews(10.0, {});
  const Scored wrong = MatchPlaneViews(10.0, {}, off);
  EXPECT_LT(wrong.matches, 0.05 * right.matches) << wrong.matches << " vs " << right.matches;
}

TEST(GuidedMatcher, BadInputIsAnError) {
  GuidedMatcherOptions options;
  options.ratio = 0;
  EXPECT_NE(options.Check().error().message.find("ratio"), std::string::npos);
  EXPECT_FALSE((DepthRange{2.0, 1.0}).Check());
  EXPECT_FALSE(MakePosedKeyframe(KeyframeFeatures{}, Rigid3d(), DepthRange{0, 1}, TestCamera()).has_value());
  KeyframeFeatures inconsistent;
  inconsistent.pixels.resize(3);
  EXPECT_FALSE(MakePosedKeyframe(inconsistent, Rigid3d(), DepthRange{1, 2}, TestCamera()).has_value());
}

}  // namespace
}  // namespace tagsfm
