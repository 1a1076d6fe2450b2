#pragma once
// SIFT features of one keyframe, outside the tags, as plain values for the
// matcher (guided_matcher.h) and the feature map (feature_map.h).
#include <array>
#include <cstdint>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "tagsfm/core/csv_formats.h"
#include "tagsfm/core/result.h"
#include "tagsfm/detect/tag_detection.h"

namespace tagsfm {

struct FeatureExtractorOptions {
  // Strongest features kept per keyframe; 0: every one SIFT finds (the
  // choice is measured in docs/features.md).
  int max_features = 0;
  // OpenCV's SIFT contrast threshold (its default 0.04 is COLMAP's
  // peak_threshold): half of it doubles the features, and the points, at the
  // same accuracy, and real indoor photos need it (docs/features.md).
  double contrast_threshold = 0.02;
  // The threshold scaled by the image's grey range outside the tags (its
  // 1st to 99th percentile over 255, at least 0.1): SIFT's threshold is on
  // absolute grey values, so a dim or low-contrast exposure loses most of
  // its features where a well exposed one of the same scene keeps them.
  bool contrast_relative_to_range = true;
  // Texture-poor views (white walls, doors, a plain object on a plain
  // background): when SIFT finds fewer features than this per megapixel of
  // the image outside the tags, it runs again at half the threshold, down
  // to min_contrast_threshold (before the range scaling). A textured view
  // keeps its features as they were; 0: never (docs/features.md).
  double min_features_per_megapixel = 4000;
  double min_contrast_threshold = 0.005;
  // RootSIFT (Arandjelovic & Zisserman 2012: L1-normalise, square root)
  // instead of plain SIFT; either way the descriptors have unit L2 norm.
  bool root_sift = true;
  double tag_margin = 0.3;  // tags are masked, grown by this fraction of their size
  // SIFT runs on the image scaled by this (<= 1); its cost goes with the
  // square, and features are localised about 1/scale times worse.
  double image_scale = 1.0;

  Status Check() const;  // names the wrong field
};

// Descriptors are kept as bytes: each component of the unit (L2) descriptor
// times kDescriptorQuantum, rounded. A quarter of the floats' memory (2.4
// instead of 9.6 MB for a 1280x720 keyframe's ~19,000 features, held for
// every keyframe of a run); RootSIFT's components stay below 0.64, so none
// is clipped, and a distance moves by ~0.01 at most (of 0-2).
constexpr double kDescriptorQuantum = 400.0;
// Unit float descriptors (CV_32F rows) as such bytes (CV_8U).
cv::Mat QuantiseDescriptors(const cv::Mat& unit_descriptors);
// And back, as floats of unit norm up to the rounding (for OpenCV's FLANN).
cv::Mat DescriptorsAsFloat(const cv::Mat& quantised);

// One keyframe's features; all vectors have one entry per feature, row i of
// `descriptors` belongs to pixels[i].
struct KeyframeFeatures {
  FrameId frame = 0;
  // OpenCV's convention (pixel centres at integers), distorted image
  // coordinates, full-size pixels.
  std::vector<Eigen::Vector2d> pixels;
  cv::Mat descriptors;  // CV_8U, 128 columns: QuantiseDescriptors of unit descriptors
  std::vector<std::array<std::uint8_t, 3>> rgb;
  std::vector<float> scale;        // SIFT keypoint diameter, full-size pixels
  std::vector<float> orientation;  // SIFT orientation, degrees
  // The keyframe's 8-bit grey image (full size), which the least-squares
  // refinement of the tracks reads (track_refinement.h); empty: the
  // keyframe's views are triangulated as SIFT found them.
  cv::Mat image;

  int size() const { return static_cast<int>(pixels.size()); }
  // The vectors agree in length, the descriptors are 128-column bytes and
  // the image, if any, is 8-bit grey.
  Status Check() const;
};

// SIFT features of `gray` (8-bit) outside the tags of `tags`; `colour`
// (8-bit BGR of the same size, or empty) gives their colours. The frame id
// is tags.frame.
Result<KeyframeFeatures> ExtractFeatures(const cv::Mat& gray, const cv::Mat& colour, const DetectionSet& tags,
                                         const FeatureExtractorOptions& options);

}  // namespace tagsfm
