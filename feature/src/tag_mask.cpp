#include "tagsfm/feature/tag_mask.h"

#include <vector>

#include <opencv2/imgproc.hpp>

namespace tagsfm {

cv::Mat MaskOutsideTags(const cv::Size& size, const DetectionSet& tags, double margin) {
  cv::Mat mask(size, CV_8U, cv::Scalar(255));
  for (const TagDetection& tag : tags.tags) {
    const Eigen::Vector2d centre = tag.Center();
    std::vector<cv::Point> polygon;
    for (const Eigen::Vector2d& corner : tag.corners) {
      const Eigen::Vector2d grown = centre + (1.0 + 2.0 * margin) * (corner - centre);
      polygon.emplace_back(cvRound(grown.x()), cvRound(grown.y()));
    }
    cv::fillConvexPoly(mask, polygon, cv::Scalar(0));
  }
  return mask;
}

}  // namespace tagsfm
