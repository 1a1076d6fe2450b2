#pragma once
// Where tags may be in an entry band of the tag tracker, by OpenCV's aruco.
#include <memory>
#include <string>
#include <vector>

#include <opencv2/aruco.hpp>

#include "tagsfm/detect/corner_refinement.h"

namespace tagsfm::detail {

// Candidate tags in an entry band, by OpenCV's aruco with the family's
// dictionary: ~5x less CPU than libapriltag on the same band (720p bench:
// 1.1 vs 5.2 ms per frame), but with aruco's own decoding and a margin it
// wants at the image's edges. So it only says where to look: libapriltag
// then searches a padded region around each candidate that no tracked
// region covers, and only what it finds counts.
class BandCandidates {
 public:
  // Null when aruco has no dictionary for the family.
  static std::unique_ptr<BandCandidates> Create(const std::string& family);

  // Corners of the candidates in `band` (band coordinates). Thread-safe:
  // the dictionary and parameters are only read.
  std::vector<QuadCorners> Find(const cv::Mat& band) const;

 private:
  BandCandidates() = default;
  cv::Ptr<cv::aruco::Dictionary> dictionary_;
  cv::Ptr<cv::aruco::DetectorParameters> parameters_;
};

}  // namespace tagsfm::detail
