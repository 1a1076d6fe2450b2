// Keyframe features: the pixel convention, the tag mask, the descriptors.
#include <cmath>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "tagsfm/feature/feature_extractor.h"

namespace tagsfm {
namespace {

cv::Mat Texture(int width, int height, unsigned seed) {
  cv::Mat noise(height, width, CV_32F);
  cv::RNG rng(seed);
  rng.fill(noise, cv::RNG::NORMAL, 0.0, 1.0);
  cv::Mat smooth, out;
  cv::GaussianBlur(noise, smooth, cv::Size(0, 0), 2.5);
  cv::normalize(smooth, out, 20, 235, cv::NORM_MINMAX, CV_8U);
  return out;
}

// An image shifted by exactly (+7, -4) px: features at the same texture
// move by that, with no offset (OpenCV's +0.25 px is removed at both ends,
// so a shift cannot show it; a zoom can: see extractor_pixel_convention_test.cpp). Here:
// the descriptors of corresponding features are near, and nearest.
TEST(FeatureExtractor, ShiftedImageGivesShiftedFeaturesWithCloseDescriptors) {
  const cv::Mat first = Texture(640, 480, 3);
  cv::Mat second;
  const cv::Mat shift = (cv::Mat_<double>(2, 3) << 1, 0, 7, 0, 1, -4);
  cv::warpAffine(first, second, shift, first.size(), cv::INTER_NEAREST, cv::BORDER_REFLECT);
  auto a = ExtractFeatures(first, cv::Mat(), DetectionSet{0, {}}, {});
  auto b = ExtractFeatures(second, cv::Mat(), DetectionSet{1, {}}, {});
  ASSERT_TRUE(a && b);
  ASSERT_TRUE(a->Check() && b->Check());
  EXPECT_GT(a->size(), 500);
  int found = 0, close = 0;
  for (int i = 0; i < a->size(); ++i) {
    const Eigen::Vector2d target = a->pixels[static_cast<size_t>(i)] + Eigen::Vector2d(7, -4);
    if (target.x() < 20 || target.y() < 20 || target.x() > 620 || target.y() > 460) continue;
    // SIFT gives a keypoint one entry per dominant orientation: the nearest
    // descriptor among those at the spot.
    double nearest = INFINITY;
    for (int j = 0; j < b->size(); ++j) {
      if ((b->pixels[static_cast<size_t>(j)] - target).norm() > 0.05) continue;
      nearest = std::min(nearest, cv::norm(a->descriptors.row(i), b->descriptors.row(j)));
    }
    if (std::isfinite(nearest)) {
      ++found;
      close += nearest < 0.1;
    }
  }
  EXPECT_GT(found, 0.8 * a->size() * 0.8);
  EXPECT_GT(close, 0.95 * found);
  for (int r = 0; r < a->descriptors.rows; ++r) EXPECT_NEAR(cv::norm(a->descriptors.row(r)), 1.0, 1e-4);
}

TEST(FeatureExtractor, NoFeaturesOnTagsAndMaxFeaturesIsHonoured) {
  const cv::Mat image = Texture(640, 480, 9);
  TagDetection tag;
  tag.id = 3;
  tag.corners = {Eigen::Vector2d(200, 300), Eigen::Vector2d(300, 300), Eigen::Vector2d(300, 200), Eigen::Vector2d(200, 200)};
  FeatureExtractorOptions options;
  auto all = ExtractFeatures(image, cv::Mat(), DetectionSet{0, {tag}}, options);
  ASSERT_TRUE(all.has_value());
  for (const Eigen::Vector2d& p : all->pixels) {
    EXPECT_FALSE(p.x() > 200 && p.x() < 300 && p.y() > 200 && p.y() < 300) << p.transpose();
  }
  options.max_features = 200;
  auto few = ExtractFeatures(image, cv::Mat(), DetectionSet{0, {tag}}, options);
  ASSERT_TRUE(few.has_value());
  EXPECT_LE(few->size(), 210);  // SIFT keeps ties at the cut
  EXPECT_GT(all->size(), few->size());
}

// The same scene exposed at 0.3 of the light: with the threshold on absolute
// grey values SIFT loses most of its features; relative to the image's grey
// range it keeps about as many as in the well exposed image.
TEST(FeatureExtractor, ADimExposureKeepsItsFeaturesWithTheRelativeThreshold) {
  const cv::Mat bright = Texture(640, 480, 21);
  cv::Mat dim;
  bright.convertTo(dim, CV_8U, 0.3);
  FeatureExtractorOptions options;
  auto on_bright = ExtractFeatures(bright, cv::Mat(), DetectionSet{0, {}}, options);
  auto on_dim = ExtractFeatures(dim, cv::Mat(), DetectionSet{1, {}}, options);
  options.contrast_relative_to_range = false;
  auto absolute_bright = ExtractFeatures(bright, cv::Mat(), DetectionSet{0, {}}, options);
  auto absolute_dim = ExtractFeatures(dim, cv::Mat(), DetectionSet{1, {}}, options);
  ASSERT_TRUE(on_bright && on_dim && absolute_bright && absolute_dim);
  std::printf("features: relative %d bright, %d dim; absolute %d bright, %d dim\n", on_bright->size(), on_dim->size(),
              absolute_bright->size(), absolute_dim->size());
  ASSERT_GT(on_bright->size(), 300);
  // 8-bit rounding of the dim image adds a little noise of its own.
  EXPECT_GT(on_dim->size(), 0.8 * on_bright->size());
  EXPECT_LT(on_dim->size(), 1.25 * on_bright->size());
  EXPECT_LT(absolute_dim->size(), 0.5 * absolute_bright->size());
  // This texture spans most of the range: the relative threshold is little lower.
  EXPECT_GE(on_bright->size(), absolute_bright->size());
  EXPECT_LT(on_bright->size(), 1.5 * absolute_bright->size());
}

TEST(FeatureExtractor, BadInputIsAnError) {
  EXPECT_FALSE(ExtractFeatures(cv::Mat(), cv::Mat(), DetectionSet{7, {}}, {}).has_value());
  FeatureExtractorOptions options;
  options.image_scale = 2;
  const Status s = options.Check();
  ASSERT_FALSE(s);
  EXPECT_NE(s.error().message.find("image_scale"), std::string::npos);
  auto tiny = ExtractFeatures(cv::Mat(1, 1, CV_8U, cv::Scalar(0)), cv::Mat(), DetectionSet{8, {}}, {});
  ASSERT_TRUE(tiny.has_value());
  EXPECT_EQ(tiny->size(), 0);
  EXPECT_TRUE(tiny->Check());
}

}  // namespace
}  // namespace tagsfm
