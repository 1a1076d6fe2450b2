#include "tagsfm/detect/tag_detection.h"

namespace tagsfm {

Eigen::Vector2d TagDetection::Center() const {
  return 0.25 * (corners[0] + corners[1] + corners[2] + corners[3]);
}

bool ClearOfImageBorder(const std::array<Eigen::Vector2d, 4>& corners, int width, int height) {
  constexpr double kMargin = 3.0;
  for (const Eigen::Vector2d& c : corners) {
    if (!(c.x() >= kMargin && c.y() >= kMargin && c.x() <= width - 1 - kMargin && c.y() <= height - 1 - kMargin)) {
      return false;
    }
  }
  return true;
}

}  // namespace tagsfm
