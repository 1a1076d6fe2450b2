// OpenCV's pixel convention for the extracted features, checked with a zoom
// of exactly known homography: SIFT's keypoints come out +0.25 px off
// (docs/features.md, "Pixel convention"), which a shift cannot show (both
// images carry it) but a zoom s can: a constant offset b shows as a mean
// residual of b (1 - s). Moved here from the old FeatureTracker's tests.
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
  int matched = 0;
  int within_1px = 0;
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
};

// Features of `first` and of `first` warped by h, matched by nearest
// descriptor (ratio 0.8), checked against h.
Residuals MatchThrough(const cv::Mat& first, const cv::Matx33d& h, const FeatureExtractorOptions& options) {
  cv::Mat second;
  cv::warpPerspective(first, second, cv::Mat(h), first.size(), cv::INTER_CUBIC, cv::BORDER_REFLECT);
  auto a = ExtractFeatures(first, cv::Mat(), DetectionSet{0, {}}, options);
  auto b = ExtractFeatures(second, cv::Mat(), DetectionSet{1, {}}, options);
  EXPECT_TRUE(a && b);
  Residuals r;
  if (!a || !b || a->size() < 2) return r;
  cv::Mat dots;  // unit descriptors: distance^2 = 2 - 2 dot
  cv::gemm(DescriptorsAsFloat(b->descriptors), DescriptorsAsFloat(a->descriptors), 1.0, cv::Mat(), 0.0, dots, cv::GEMM_2_T);
  for (int i = 0; i < b->size(); ++i) {
    double best = -2, second_best = -2;
    int best_j = -1;
    for (int j = 0; j < a->size(); ++j) {
      const double d = dots.at<float>(i, j);
      if (d > best) {
        second_best = best;
        best = d;
        best_j = j;
      } else if (d > second_best) {
        second_best = d;
      }
    }
    if (std::sqrt(std::max(0.0, 2 - 2 * best)) > 0.8 * std::sqrt(std::max(0.0, 2 - 2 * second_best))) continue;
    const Eigen::Vector2d residual = b->pixels[static_cast<size_t>(i)] - Apply(h, a->pixels[static_cast<size_t>(best_j)]);
    ++r.matched;
    if (residual.norm() < 1.0) {
      ++r.within_1px;
      r.mean += residual;
    }
  }
  if (r.within_1px > 0) r.mean /= r.within_1px;
  return r;
}

// A zoom of 1.5 about the image centre with a slight turn and tilt.
TEST(ExtractorPixelConvention, FeaturesFollowAKnownHomographyWithoutOffset) {
  const cv::Mat first = Texture(640, 480, 5);
  const double a = 5.0 * M_PI / 180.0, s = 1.5;
  const cv::Matx33d to_centre(1, 0, -320, 0, 1, -240, 0, 0, 1), back(1, 0, 320, 0, 1, 240, 0, 0, 1);
  const cv::Matx33d zoom(s * std::cos(a), -s * std::sin(a), 0, s * std::sin(a), s * std::cos(a), 0, 2e-5, 1e-5, 1);
  const Residuals r = MatchThrough(first, back * zoom * to_centre, {});
  EXPECT_GE(r.within_1px, 200);
  // 0.02 px: the mean of several hundred residuals of ~0.1-0.2 px each
  // (an uncorrected offset would show as 0.125 px).
  EXPECT_LT(std::abs(r.mean.x()), 0.02) << "mean residual " << r.mean.transpose();
  EXPECT_LT(std::abs(r.mean.y()), 0.02) << "mean residual " << r.mean.transpose();
}

// SIFT on the image at half size: the keypoints map back to full-size
// pixels without an offset either (residuals about twice as large, so twice
// the bound).
TEST(ExtractorPixelConvention, HalfSizeImageKeepsThePixelConvention) {
  const cv::Mat first = Texture(960, 720, 5);
  const double s = 1.5;
  const cv::Matx33d h(s, 0, -0.5 * (s - 1) * 960, 0, s, -0.5 * (s - 1) * 720, 0, 0, 1);
  FeatureExtractorOptions options;
  options.image_scale = 0.5;
  const Residuals r = MatchThrough(first, h, options);
  EXPECT_GE(r.within_1px, 100);
  EXPECT_LT(std::abs(r.mean.x()), 0.04) << "mean residual " << r.mean.transpose();
  EXPECT_LT(std::abs(r.mean.y()), 0.04) << "mean residual " << r.mean.transpose();
}

}  // namespace
}  // namespace tagsfm
