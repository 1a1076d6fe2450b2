#pragma once
// Natural features (SIFT) tracked from frame to frame, for the points around
// the targets: the "SfM" half of the hybrid pipeline. The targets give the
// camera poses; these tracks only need to be correct correspondences, which
// the tracker makes sure of by Lowe's ratio test, a mutual best-match check
// and an epipolar (fundamental matrix) RANSAC between consecutive calls.
#include <array>
#include <cstdint>
#include <memory>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "tagsfm/core/result.h"
#include "tagsfm/detect/tag_detection.h"

namespace tagsfm {

using TrackId = std::int64_t;

struct FeatureTrackerOptions {
  int max_features = 2000;        // strongest SIFT features kept per frame
  double ratio = 0.8;             // Lowe's ratio test: best / second-best descriptor distance
  double epipolar_px = 1.5;       // RANSAC threshold of the fundamental matrix check, px
  int min_matches = 20;           // fewer verified matches: no track continues (the check is unreliable)
  double tag_margin = 0.3;        // tags are masked, grown by this fraction of their size: they are targets
  // SIFT runs on the image scaled by this (<= 1). SIFT first doubles its
  // input, so its cost goes with the square of this; 0.5 is ~4x cheaper and
  // localises features about half as well.
  double image_scale = 1.0;

  Status Check() const;
};

struct FeatureObservation {
  TrackId track = -1;
  Eigen::Vector2d pixel = Eigen::Vector2d::Zero();  // OpenCV convention, distorted coordinates
  std::array<std::uint8_t, 3> rgb{0, 0, 0};
};

struct FeatureSet {
  FrameId frame = 0;
  std::vector<FeatureObservation> features;
  int continued = 0;  // features that continue a track of the previous call
};

class FeatureTracker {
 public:
  static Result<std::unique_ptr<FeatureTracker>> Create(const FeatureTrackerOptions& options);
  ~FeatureTracker();

  // Features of `gray` (8-bit) outside the tags of `tags`; those matched to
  // the previous call's features continue their tracks, the others start new
  // ones. `colour` (8-bit BGR, or empty) gives the features' colours.
  Result<FeatureSet> Track(const cv::Mat& gray, const cv::Mat& colour, const DetectionSet& tags);

 private:
  struct State;
  explicit FeatureTracker(std::unique_ptr<State> state);
  std::unique_ptr<State> state_;
};

}  // namespace tagsfm
