#pragma once
// What detection hands to reconstruction: plain values, no library types.
#include <array>
#include <vector>

#include <Eigen/Core>

#include "tagsfm/core/csv_formats.h"

namespace tagsfm {

struct TagDetection {
  TagId id = -1;
  // libapriltag's corner order, in OpenCV's pixel convention (pixel centres
  // at integer coordinates), distorted image coordinates.
  std::array<Eigen::Vector2d, 4> corners;
  double decision_margin = 0.0;
  int hamming = 0;

  Eigen::Vector2d Center() const;
};

struct DetectionSet {
  FrameId frame = 0;
  std::vector<TagDetection> tags;
};

}  // namespace tagsfm
