#include "band_candidates.h"

#include "aruco_dictionary.h"

namespace tagsfm::detail {

std::unique_ptr<BandCandidates> BandCandidates::Create(const std::string& family) {
  cv::Ptr<cv::aruco::Dictionary> dictionary = ArucoDictionaryFor(family);
  if (!dictionary) return nullptr;
  auto candidates = std::unique_ptr<BandCandidates>(new BandCandidates);
  candidates->dictionary_ = dictionary;
  candidates->parameters_ = cv::aruco::DetectorParameters::create();
  // A tag that has just entered may lie a pixel from the image's edge.
  candidates->parameters_->minDistanceToBorder = 1;
  // Bits read at 8 px per module, ignoring 30 % of a module at its
  // edges: finds far more small and strongly tilted tags than aruco's
  // defaults (4 px, 13 %): 1280x720, 120 tags of 24 px tilted <= 50 deg,
  // 116 vs 92 (libapriltag at quad_decimate 2: 105), at the same cost.
  candidates->parameters_->perspectiveRemovePixelPerCell = 8;
  candidates->parameters_->perspectiveRemoveIgnoredMarginPerCell = 0.3;
  return candidates;
}

std::vector<QuadCorners> BandCandidates::Find(const cv::Mat& band) const {
  std::vector<std::vector<cv::Point2f>> corners;
  std::vector<int> ids;
  cv::aruco::detectMarkers(band, dictionary_, corners, ids, parameters_);
  std::vector<QuadCorners> quads;
  for (const std::vector<cv::Point2f>& marker : corners) {
    if (marker.size() != 4) continue;
    QuadCorners quad;
    for (int k = 0; k < 4; ++k) quad[k] = Eigen::Vector2d(marker[k].x, marker[k].y);
    quads.push_back(quad);
  }
  return quads;
}

}  // namespace tagsfm::detail
