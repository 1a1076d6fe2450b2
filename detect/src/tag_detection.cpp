#include "tagsfm/detect/tag_detection.h"

namespace tagsfm {

Eigen::Vector2d TagDetection::Center() const {
  return 0.25 * (corners[0] + corners[1] + corners[2] + corners[3]);
}

bool ClearOfImageBorder(const std::array<Eigen::Vector2d, 4>& corners, int width, int height) {
  return WhollyInsideImage(corners, width, height, 3.0);
}

bool WhollyInsideImage(const std::array<Eigen::Vector2d, 4>& corners, int width, int height, double margin_px) {
  for (const Eigen::Vector2d& c : corners) {
    if (!(c.x() >= margin_px && c.y() >= margin_px && c.x() <= width - 1 - margin_px &&
          c.y() <= height - 1 - margin_px)) {
      return false;
    }
  }
  return true;
}

}  // namespace tagsfm
