#include "tagsfm/feature/feature_extractor.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <string>

#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include "tagsfm/feature/tag_mask.h"

namespace tagsfm {

Status FeatureExtractorOptions::Check() const {
  if (max_features < 0) return MakeError("features.max_features must be >= 0 (0: no limit)");
  if (!(contrast_threshold > 0 && contrast_threshold < 1)) return MakeError("features.contrast_threshold must be in (0, 1)");
  if (!(min_features_per_megapixel >= 0)) return MakeError("features.min_features_per_megapixel must be >= 0");
  if (!(min_contrast_threshold > 0 && min_contrast_threshold <= contrast_threshold)) {
    return MakeError("features.min_contrast_threshold must be in (0, contrast_threshold]");
  }
  if (!(tag_margin >= 0)) return MakeError("features.tag_margin must be >= 0");
  if (!(image_scale > 0.1 && image_scale <= 1)) return MakeError("features.image_scale must be in (0.1, 1]");
  return Status::Ok();
}

Status KeyframeFeatures::Check() const {
  const size_t n = pixels.size();
  const std::string where = "frame " + std::to_string(frame) + ": ";
  if (rgb.size() != n || scale.size() != n || orientation.size() != n) return MakeError(where + "features' pixels, rgb, scale and orientation differ in length");
  if (n > 0 && (descriptors.type() != CV_8U || descriptors.cols != 128 || static_cast<size_t>(descriptors.rows) != n)) {
    return MakeError(where + "features need one 128-byte descriptor per pixel");
  }
  if (!image.empty() && image.type() != CV_8UC1) return MakeError(where + "the features' image must be 8-bit grey");
  return Status::Ok();
}

cv::Mat QuantiseDescriptors(const cv::Mat& unit_descriptors) {
  cv::Mat bytes;
  unit_descriptors.convertTo(bytes, CV_8U, kDescriptorQuantum);  // rounds and saturates
  return bytes;
}

cv::Mat DescriptorsAsFloat(const cv::Mat& quantised) {
  cv::Mat floats;
  quantised.convertTo(floats, CV_32F, 1.0 / kDescriptorQuantum);
  return floats;
}

namespace {

// Unit-L2 descriptors; RootSIFT compares them by the Hellinger kernel, which
// matches better than L2 on SIFT histograms.
void NormaliseDescriptors(cv::Mat& descriptors, bool root_sift) {
  for (int r = 0; r < descriptors.rows; ++r) {
    float* d = descriptors.ptr<float>(r);
    if (root_sift) {
      double l1 = 0;
      for (int c = 0; c < descriptors.cols; ++c) l1 += std::abs(d[c]);
      const double inv = l1 > 0 ? 1.0 / l1 : 0.0;
      for (int c = 0; c < descriptors.cols; ++c) d[c] = static_cast<float>(std::sqrt(std::abs(d[c]) * inv));
    } else {
      double l2 = 0;
      for (int c = 0; c < descriptors.cols; ++c) l2 += double(d[c]) * d[c];
      const double inv = l2 > 0 ? 1.0 / std::sqrt(l2) : 0.0;
      for (int c = 0; c < descriptors.cols; ++c) d[c] = static_cast<float>(d[c] * inv);
    }
  }
}

std::array<std::uint8_t, 3> ColourAt(const cv::Mat& gray, const cv::Mat& colour, const Eigen::Vector2d& pixel) {
  const cv::Point p(std::clamp(cvRound(pixel.x()), 0, gray.cols - 1), std::clamp(cvRound(pixel.y()), 0, gray.rows - 1));
  if (colour.type() == CV_8UC3 && colour.size() == gray.size()) {
    const cv::Vec3b bgr = colour.at<cv::Vec3b>(p);
    return {bgr[2], bgr[1], bgr[0]};
  }
  const std::uint8_t g = gray.at<std::uint8_t>(p);
  return {g, g, g};
}

// Grey range between the 1st and 99th percentiles of the pixels `mask`
// keeps (every other row and column), over 255; 1 for an empty mask.
double GreyRangeFraction(const cv::Mat& gray, const cv::Mat& mask) {
  std::array<long, 256> histogram{};
  long total = 0;
  for (int r = 0; r < gray.rows; r += 2) {
    const std::uint8_t* g = gray.ptr<std::uint8_t>(r);
    const std::uint8_t* m = mask.ptr<std::uint8_t>(r);
    for (int c = 0; c < gray.cols; c += 2) {
      if (m[c] == 0) continue;
      ++histogram[g[c]];
      ++total;
    }
  }
  if (total == 0) return 1.0;
  const auto percentile = [&](double share) {
    long seen = 0;
    for (int v = 0; v < 256; ++v) {
      seen += histogram[static_cast<size_t>(v)];
      if (static_cast<double>(seen) > share * static_cast<double>(total)) return v;
    }
    return 255;
  };
  return (percentile(0.99) - percentile(0.01)) / 255.0;
}

}  // namespace

Result<KeyframeFeatures> ExtractFeatures(const cv::Mat& gray, const cv::Mat& colour, const DetectionSet& tags,
                                         const FeatureExtractorOptions& options) {
  if (Status s = options.Check(); !s) return s.error();
  if (gray.empty() || gray.type() != CV_8UC1) return MakeError("frame " + std::to_string(tags.frame) + ": features need an 8-bit grey image");
  const cv::Mat full_mask = MaskOutsideTags(gray.size(), tags, options.tag_margin);
  const double range = options.contrast_relative_to_range ? std::clamp(GreyRangeFraction(gray, full_mask), 0.1, 1.0) : 1.0;
  const double scale = options.image_scale;
  cv::Mat image = gray, mask = full_mask;
  if (scale < 1.0) {
    cv::resize(gray, image, cv::Size(), scale, scale, cv::INTER_AREA);
    cv::resize(full_mask, mask, image.size(), 0, 0, cv::INTER_NEAREST);
  }
  const double floor = options.min_features_per_megapixel * cv::countNonZero(mask) * 1e-6 / (scale * scale);
  std::vector<cv::KeyPoint> keypoints;
  cv::Mat descriptors;
  for (double threshold = options.contrast_threshold;; threshold *= 0.5) {
    threshold = std::max(threshold, options.min_contrast_threshold);
    keypoints.clear();
    cv::SIFT::create(options.max_features, 3, threshold * range)->detectAndCompute(image, mask, keypoints, descriptors);
    if (static_cast<double>(keypoints.size()) >= floor || threshold <= options.min_contrast_threshold) break;
  }
  NormaliseDescriptors(descriptors, options.root_sift);

  // OpenCV 4.6's SIFT doubles the image first (pixel-centre aligned) but
  // halves the keypoints' coordinates as if corner aligned: every keypoint
  // comes out +0.25 px in x and y (measured with a zoom of known homography,
  // docs/features.md); a 0.25 px shift would bias every point by about
  // depth * 0.25 / f.
  constexpr double kSiftOffsetPx = 0.25;
  KeyframeFeatures out;
  out.frame = tags.frame;
  out.descriptors = QuantiseDescriptors(descriptors);
  out.image = gray.clone();  // the caller may reuse its buffer
  const size_t n = keypoints.size();
  out.pixels.reserve(n);
  out.rgb.reserve(n);
  out.scale.reserve(n);
  out.orientation.reserve(n);
  for (const cv::KeyPoint& k : keypoints) {
    // Back to full-size pixels, pixel centres at integers at both scales.
    const Eigen::Vector2d pixel((k.pt.x - kSiftOffsetPx + 0.5) / scale - 0.5, (k.pt.y - kSiftOffsetPx + 0.5) / scale - 0.5);
    out.pixels.push_back(pixel);
    out.rgb.push_back(ColourAt(gray, colour, pixel));
    out.scale.push_back(static_cast<float>(k.size / scale));
    out.orientation.push_back(k.angle);
  }
  if (n == 0) out.descriptors = cv::Mat(0, 128, CV_8U);
  return out;
}

}  // namespace tagsfm
