// Keyframe features: the pixel convention, the tag mask, the descriptors.
#include <algorithm>
#include <cmath>
#include <vector>

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
      nearest = std::min(nearest, cv::norm(DescriptorsAsFloat(a->descriptors.row(i)), DescriptorsAsFloat(b->descriptors.row(j))));
    }
    if (std::isfinite(nearest)) {
      ++found;
      close += nearest < 0.1;
    }
  }
  EXPECT_GT(found, 0.8 * a->size() * 0.8);
  EXPECT_GT(close, 0.95 * found);
  // Unit descriptors, kept as bytes: the norm is 1 up to the rounding of
  // 128 components by at most half a quantum each.
  const cv::Mat unit = DescriptorsAsFloat(a->descriptors);
  for (int r = 0; r < unit.rows; ++r) EXPECT_NEAR(cv::norm(unit.row(r)), 1.0, 0.5 * std::sqrt(128.0) / kDescriptorQuantum);
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
  options.min_features_per_megapixel = 0;  // the threshold alone (the floor has its own test)
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

// A plain wall: stucco of +-14 grey levels, with a dark door frame that sets
// the grey range. At the threshold SIFT finds few features there; the
// floor runs it again lower. The features it had are kept, the new ones
// are located as well (the image shifted by a whole number of pixels), and
// a textured view is left as it was.
cv::Mat PlainWall(int width, int height, unsigned seed) {
  cv::Mat wall;
  Texture(width, height, seed).convertTo(wall, CV_8U, 28.0 / 215, 190 - 20 * 28.0 / 215);
  cv::rectangle(wall, cv::Rect(width / 2 - 20, 0, 40, height), cv::Scalar(40), cv::FILLED);
  return wall;
}

TEST(FeatureExtractor, ATexturePoorViewIsExtractedAgainAtALowerThreshold) {
  const cv::Mat wall = PlainWall(640, 480, 5);
  FeatureExtractorOptions without_floor;
  without_floor.min_features_per_megapixel = 0;
  auto few = ExtractFeatures(wall, cv::Mat(), DetectionSet{0, {}}, without_floor);
  auto more = ExtractFeatures(wall, cv::Mat(), DetectionSet{0, {}}, {});
  ASSERT_TRUE(few && more);
  const double floor = FeatureExtractorOptions().min_features_per_megapixel * 640 * 480 * 1e-6;
  std::printf("plain wall: %d features at the threshold, %d with the floor (%.0f)\n", few->size(), more->size(), floor);
  ASSERT_LT(few->size(), floor);
  EXPECT_GT(more->size(), 2 * few->size());
  int kept = 0;
  for (const Eigen::Vector2d& p : few->pixels) {
    kept += std::any_of(more->pixels.begin(), more->pixels.end(), [&](const Eigen::Vector2d& q) { return (p - q).norm() < 1e-3; });
  }
  EXPECT_GT(kept, 0.95 * few->size());

  // The wall moved by (+7, -4): features of the shifted wall at the
  // shifted spot, as close as on a textured view (the shift test above).
  cv::Mat moved;
  const cv::Mat shift = (cv::Mat_<double>(2, 3) << 1, 0, 7, 0, 1, -4);
  cv::warpAffine(wall, moved, shift, wall.size(), cv::INTER_NEAREST, cv::BORDER_REFLECT);
  auto on_moved = ExtractFeatures(moved, cv::Mat(), DetectionSet{1, {}}, {});
  ASSERT_TRUE(on_moved.has_value());
  std::vector<double> errors;
  for (const Eigen::Vector2d& p : more->pixels) {
    const Eigen::Vector2d target = p + Eigen::Vector2d(7, -4);
    if (target.x() < 20 || target.y() < 20 || target.x() > 620 || target.y() > 460) continue;
    double nearest = INFINITY;
    for (const Eigen::Vector2d& q : on_moved->pixels) nearest = std::min(nearest, (q - target).norm());
    if (nearest < 1.0) errors.push_back(nearest);
  }
  ASSERT_GT(errors.size(), 0.7 * more->size());
  std::nth_element(errors.begin(), errors.begin() + static_cast<long>(errors.size() / 2), errors.end());
  EXPECT_LT(errors[errors.size() / 2], 0.01);

  // A textured view has more than the floor at the threshold: untouched.
  const cv::Mat textured = Texture(640, 480, 3);
  auto plain = ExtractFeatures(textured, cv::Mat(), DetectionSet{0, {}}, without_floor);
  auto with_floor = ExtractFeatures(textured, cv::Mat(), DetectionSet{0, {}}, {});
  ASSERT_TRUE(plain && with_floor);
  ASSERT_GE(plain->size(), floor);
  EXPECT_EQ(plain->pixels, with_floor->pixels);
}

// Descriptors kept as bytes: distances between them within ~0.01 of the
// floats' (the matcher's ratio test and distance limit see the same
// values), and no component of a real RootSIFT descriptor clipped at 255.
TEST(FeatureExtractor, DescriptorsAsBytesKeepTheirDistances) {
  cv::Mat unit(200, 128, CV_32F);
  cv::RNG rng(4);
  rng.fill(unit, cv::RNG::UNIFORM, 0.0, 1.0);
  for (int r = 0; r < unit.rows; ++r) {
    cv::pow(unit.row(r), 3.0, unit.row(r));  // peaky, like SIFT's histograms
    cv::normalize(unit.row(r), unit.row(r));
  }
  const cv::Mat back = DescriptorsAsFloat(QuantiseDescriptors(unit));
  double worst = 0;
  for (int a = 0; a < unit.rows; ++a) {
    for (int b = a + 1; b < unit.rows; b += 7) {
      worst = std::max(worst, std::abs(cv::norm(unit.row(a), unit.row(b)) - cv::norm(back.row(a), back.row(b))));
    }
  }
  EXPECT_LT(worst, std::sqrt(128.0) / kDescriptorQuantum);  // every component off by half a quantum, both sides
  EXPECT_LT(worst, 0.03);

  for (unsigned seed : {3u, 9u}) {
    auto features = ExtractFeatures(Texture(640, 480, seed), cv::Mat(), DetectionSet{0, {}}, {});
    ASSERT_TRUE(features.has_value());
    double max_byte = 0;
    cv::minMaxLoc(features->descriptors, nullptr, &max_byte);
    EXPECT_LT(max_byte, 255) << "a component clipped";
  }
}

TEST(FeatureExtractor, BadInputIsAnError) {
  EXPECT_FALSE(ExtractFeatures(cv::Mat(), cv::Mat(), DetectionSet{7, {}}, {}).has_value());
  FeatureExtractorOptions options;
  options.image_scale = 2;
  const Status s = options.Check();
  ASSERT_FALSE(s);
  EXPECT_NE(s.error().message.find("image_scale"), std::string::npos);
  options = {};
  options.min_contrast_threshold = 2 * options.contrast_threshold;
  const Status above = options.Check();
  ASSERT_FALSE(above);
  EXPECT_NE(above.error().message.find("min_contrast_threshold"), std::string::npos);
  auto tiny = ExtractFeatures(cv::Mat(1, 1, CV_8U, cv::Scalar(0)), cv::Mat(), DetectionSet{8, {}}, {});
  ASSERT_TRUE(tiny.has_value());
  EXPECT_EQ(tiny->size(), 0);
  EXPECT_TRUE(tiny->Check());
}

}  // namespace
}  // namespace tagsfm
