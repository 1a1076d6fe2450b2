// SIFT feature tracks between two views of a textured plane, related by an
// exactly known homography.
#include <cmath>
#include <random>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "tagsfm/feature/feature_tracker.h"

namespace tagsfm {
namespace {

cv::Mat Texture(int width, int height, unsigned seed) {
  cv::Mat noise(height, width, CV_32F);
  cv::RNG rng(seed);
  rng.fill(noise, cv::RNG::NORMAL, 0.0, 1.0);
  cv::Mat smooth;
  cv::GaussianBlur(noise, smooth, cv::Size(0, 0), 2.5);
  cv::Mat out;
  cv::normalize(smooth, out, 20, 235, cv::NORM_MINMAX, CV_8U);
  return out;
}

Eigen::Vector2d Apply(const cv::Matx33d& h, const Eigen::Vector2d& p) {
  const cv::Vec3d q = h * cv::Vec3d(p.x(), p.y(), 1.0);
  return Eigen::Vector2d(q[0] / q[2], q[1] / q[2]);
}

struct Residuals {
  int continued = 0;
  int within_1px = 0;
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
};

// Tracks from `first` to `second` (= first warped by h), checked against h.
Residuals TrackThrough(const cv::Mat& first, const cv::Matx33d& h, const DetectionSet& tags_second,
                       const FeatureTrackerOptions& options = {}) {
  cv::Mat second;
  cv::warpPerspective(first, second, cv::Mat(h), first.size(), cv::INTER_CUBIC, cv::BORDER_REFLECT);
  auto tracker = FeatureTracker::Create(options);
  EXPECT_TRUE(tracker.has_value());
  auto a = (*tracker)->Track(first, cv::Mat(), DetectionSet{0, {}});
  auto b = (*tracker)->Track(second, cv::Mat(), tags_second);
  EXPECT_TRUE(a && b);
  Residuals r;
  if (!a || !b) return r;
  std::map<TrackId, Eigen::Vector2d> in_first;
  for (const auto& f : a->features) in_first[f.track] = f.pixel;
  for (const auto& f : b->features) {
    auto it = in_first.find(f.track);
    if (it == in_first.end()) continue;
    const Eigen::Vector2d residual = f.pixel - Apply(h, it->second);
    ++r.continued;
    if (residual.norm() < 1.0) {
      ++r.within_1px;
      r.mean += residual;
    }
  }
  EXPECT_EQ(r.continued, b->continued);
  if (r.within_1px > 0) r.mean /= r.within_1px;
  return r;
}

// A zoom of 1.5 about the image centre with a slight turn and tilt. Every
// continued track must follow the homography (the epipolar check lets
// through only matches within ~1.5 px of an epipolar line; a wrong match on
// its line is rare); and the keypoints must follow OpenCV's pixel
// convention: a constant offset b of all keypoints would show as a mean
// residual of b (1 - 1.5) = -b/2.
TEST(FeatureTracker, TracksFollowAKnownHomographyWithoutOffset) {
  const cv::Mat first = Texture(640, 480, 5);
  const double a = 5.0 * M_PI / 180.0, s = 1.5;
  const cv::Matx33d to_centre(1, 0, -320, 0, 1, -240, 0, 0, 1), back(1, 0, 320, 0, 1, 240, 0, 0, 1);
  const cv::Matx33d zoom(s * std::cos(a), -s * std::sin(a), 0, s * std::sin(a), s * std::cos(a), 0, 2e-5, 1e-5, 1);
  const cv::Matx33d h = back * zoom * to_centre;
  const Residuals r = TrackThrough(first, h, DetectionSet{1, {}});
  EXPECT_GE(r.continued, 200);
  EXPECT_GE(r.within_1px, 0.97 * r.continued) << r.within_1px << " of " << r.continued;
  // 0.02 px: the mean of several hundred residuals of ~0.1-0.2 px each.
  EXPECT_LT(std::abs(r.mean.x()), 0.02) << "mean residual " << r.mean.transpose();
  EXPECT_LT(std::abs(r.mean.y()), 0.02) << "mean residual " << r.mean.transpose();
}

// SIFT on the image at half size: the keypoints map back to full-size
// pixels without an offset either (the same zoom; residuals about twice as
// large, so twice the bound).
TEST(FeatureTracker, HalfSizeImageKeepsThePixelConvention) {
  const cv::Mat first = Texture(960, 720, 5);
  const double s = 1.5;
  const cv::Matx33d h(s, 0, -0.5 * (s - 1) * 960, 0, s, -0.5 * (s - 1) * 720, 0, 0, 1);
  FeatureTrackerOptions options;
  options.image_scale = 0.5;
  const Residuals r = TrackThrough(first, h, DetectionSet{1, {}}, options);
  EXPECT_GE(r.continued, 100);
  EXPECT_GE(r.within_1px, 0.95 * r.continued) << r.within_1px << " of " << r.continued;
  EXPECT_LT(std::abs(r.mean.x()), 0.04) << "mean residual " << r.mean.transpose();
  EXPECT_LT(std::abs(r.mean.y()), 0.04) << "mean residual " << r.mean.transpose();
}

TEST(FeatureTracker, NoFeaturesOnTags) {
  const cv::Mat first = Texture(640, 480, 9);
  TagDetection tag;
  tag.id = 3;
  tag.corners = {Eigen::Vector2d(200, 300), Eigen::Vector2d(300, 300), Eigen::Vector2d(300, 200), Eigen::Vector2d(200, 200)};
  auto tracker = FeatureTracker::Create({});
  ASSERT_TRUE(tracker.has_value());
  auto set = (*tracker)->Track(first, cv::Mat(), DetectionSet{0, {tag}});
  ASSERT_TRUE(set.has_value());
  EXPECT_GT(set->features.size(), 100u);
  for (const auto& f : set->features) {
    const bool inside = f.pixel.x() > 200 && f.pixel.x() < 300 && f.pixel.y() > 200 && f.pixel.y() < 300;
    EXPECT_FALSE(inside) << f.pixel.transpose();
  }
}

TEST(FeatureTracker, UnrelatedImagesContinueNoTrack) {
  auto tracker = FeatureTracker::Create({});
  ASSERT_TRUE(tracker.has_value());
  ASSERT_TRUE((*tracker)->Track(Texture(640, 480, 1), cv::Mat(), DetectionSet{0, {}}).has_value());
  auto second = (*tracker)->Track(Texture(640, 480, 2), cv::Mat(), DetectionSet{1, {}});
  ASSERT_TRUE(second.has_value());
  EXPECT_EQ(second->continued, 0);
}

TEST(FeatureTracker, BadInputIsAnError) {
  FeatureTrackerOptions options;
  options.ratio = 1.5;
  EXPECT_FALSE(FeatureTracker::Create(options).has_value());
  auto tracker = FeatureTracker::Create({});
  ASSERT_TRUE(tracker.has_value());
  EXPECT_FALSE((*tracker)->Track(cv::Mat(), cv::Mat(), DetectionSet{7, {}}).has_value());
  EXPECT_TRUE((*tracker)->Track(cv::Mat(1, 1, CV_8U, cv::Scalar(0)), cv::Mat(), DetectionSet{8, {}}).has_value());
}

}  // namespace
}  // namespace tagsfm
