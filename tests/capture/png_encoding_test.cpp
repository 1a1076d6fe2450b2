#include "tagsfm/capture/png_encoding.h"

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

namespace tagsfm {
namespace {

// A camera-like frame: smooth shading, a blurred texture, sharp edges and
// sensor noise (sigma 2 grey levels), in the given type; odd sizes so that
// rows are not a multiple of any word.
cv::Mat CameraLikeFrame(int type, int rows = 97, int cols = 131, std::uint64_t seed = 7) {
  cv::RNG rng(seed);
  cv::Mat texture(rows, cols, CV_32F);
  rng.fill(texture, cv::RNG::UNIFORM, 0, 255);
  cv::GaussianBlur(texture, texture, cv::Size(0, 0), 1.5);
  cv::Mat grey(rows, cols, CV_32F);
  for (int y = 0; y < rows; ++y) {
    for (int x = 0; x < cols; ++x) {
      const float shading = 60.0f + 80.0f * float(x) / float(cols);
      const float edge = ((x / 23 + y / 17) % 2) ? 40.0f : 0.0f;
      grey.at<float>(y, x) = shading + edge + 0.4f * (texture.at<float>(y, x) - 128.0f);
    }
  }
  cv::Mat noise(rows, cols, CV_32F);
  rng.fill(noise, cv::RNG::NORMAL, 0, 2);
  grey += noise;
  const int channels = CV_MAT_CN(type);
  std::vector<cv::Mat> planes;
  for (int c = 0; c < channels; ++c) planes.push_back(grey * (1.0 - 0.15 * c) + 5.0 * c);
  cv::Mat merged;
  cv::merge(planes, merged);
  cv::Mat out;
  const double scale = CV_MAT_DEPTH(type) == CV_16U ? 257.0 : 1.0;
  merged.convertTo(out, type, scale);
  return out;
}

TEST(PngEncoding, EveryTypeReadsBackToTheSamePixels) {
  for (const int type : {CV_8UC1, CV_8UC3, CV_8UC4, CV_16UC1, CV_16UC3, CV_16UC4}) {
    const cv::Mat image = CameraLikeFrame(type);
    const Result<std::vector<unsigned char>> png = EncodePng(image);
    ASSERT_TRUE(png) << png.error().message;
    const cv::Mat back = cv::imdecode(*png, cv::IMREAD_UNCHANGED);
    ASSERT_EQ(back.type(), type) << "type " << type;
    ASSERT_EQ(back.size(), image.size());
    EXPECT_EQ(cv::norm(back, image, cv::NORM_INF), 0) << "type " << type;
  }
  // A view into a larger image: its rows are not contiguous.
  const cv::Mat big = CameraLikeFrame(CV_8UC1, 120, 160);
  const cv::Mat view = big(cv::Rect(3, 5, 101, 77));
  const auto png = EncodePng(view);
  ASSERT_TRUE(png) << png.error().message;
  EXPECT_EQ(cv::norm(cv::imdecode(*png, cv::IMREAD_UNCHANGED), view, cv::NORM_INF), 0);
}

// The Up filter under zlib's run-length strategy is chosen for speed; it
// must not cost disk: on camera-like frames it is no larger than OpenCV's
// own writer at the same level (measured 2-13 % smaller, docs/capture.md).
TEST(PngEncoding, NoLargerThanOpenCvsWriterOnCameraLikeFrames) {
  for (const std::uint64_t seed : {1u, 2u, 3u}) {
    const cv::Mat image = CameraLikeFrame(CV_8UC1, 360, 640, seed);
    const auto ours = EncodePng(image);
    ASSERT_TRUE(ours) << ours.error().message;
    std::vector<unsigned char> opencv;
    ASSERT_TRUE(cv::imencode(".png", image, opencv, {cv::IMWRITE_PNG_COMPRESSION, 1}));
    EXPECT_LE(ours->size(), opencv.size()) << "seed " << seed;
  }
}

TEST(PngEncoding, RefusesWhatPngCannotHoldWithAMessage) {
  const std::pair<cv::Mat, std::string> cases[] = {
      {cv::Mat(), "empty"},
      {cv::Mat(8, 8, CV_32FC1, cv::Scalar(1)), "8- and 16-bit"},
      {cv::Mat(8, 8, CV_8UC2, cv::Scalar(1, 2)), "2 channels"},
  };
  for (const auto& [image, words] : cases) {
    const auto png = EncodePng(image);
    ASSERT_FALSE(png) << words;
    EXPECT_NE(png.error().message.find(words), std::string::npos) << png.error().message;
  }
}

}  // namespace
}  // namespace tagsfm
