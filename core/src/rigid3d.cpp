#include "tagsfm/core/rigid3d.h"

#include <cmath>

namespace tagsfm {

double RotationAngleDeg(const Eigen::Quaterniond& a, const Eigen::Quaterniond& b) {
  return a.angularDistance(b) * 180.0 / M_PI;
}

}  // namespace tagsfm
