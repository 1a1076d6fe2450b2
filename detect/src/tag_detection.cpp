#include "tagsfm/detect/tag_detection.h"

namespace tagsfm {

Eigen::Vector2d TagDetection::Center() const {
  return 0.25 * (corners[0] + corners[1] + corners[2] + corners[3]);
}

}  // namespace tagsfm
