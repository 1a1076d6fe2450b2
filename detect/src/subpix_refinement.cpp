// Corner refinement with OpenCV's cornerSubPix (for comparison with the edge
// line fit; see docs/detection.md).
#include <algorithm>
#include <cmath>
#include <vector>

#include <opencv2/imgproc.hpp>

#include "tagsfm/detect/corner_refinement.h"

namespace tagsfm {

bool RefineCornersBySubPix(const cv::Mat& gray8, int modules_across, QuadCorners* corners) {
  if (gray8.empty() || gray8.type() != CV_8UC1 || modules_across <= 0) return false;
  double mean_side = 0.0;
  for (int i = 0; i < 4; ++i) mean_side += 0.25 * ((*corners)[(i + 1) % 4] - (*corners)[i]).norm();
  const double module_px = mean_side / modules_across;
  // The window must not reach the border's inner corner, one module in.
  const int half_window = std::max(2, static_cast<int>(std::floor(0.75 * module_px)));
  std::vector<cv::Point2f> points;
  for (const Eigen::Vector2d& c : *corners) {
    if (c.x() < half_window + 1 || c.y() < half_window + 1 || c.x() > gray8.cols - half_window - 2 ||
        c.y() > gray8.rows - half_window - 2) {
      return false;
    }
    points.emplace_back(static_cast<float>(c.x()), static_cast<float>(c.y()));
  }
  cv::cornerSubPix(gray8, points, cv::Size(half_window, half_window), cv::Size(-1, -1),
                   cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 40, 0.001));
  const double max_move = std::max(1.5, 0.5 * module_px);
  QuadCorners refined;
  for (int i = 0; i < 4; ++i) {
    refined[i] = Eigen::Vector2d(points[i].x, points[i].y);
    if (!((refined[i] - (*corners)[i]).norm() <= max_move)) return false;
  }
  *corners = refined;
  return true;
}

}  // namespace tagsfm
