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
  // Each corner's covariance in image pixels from the edge fit
  // (RefineCornersByEdgeLines); zero when unknown (another refinement).
  std::array<Eigen::Matrix2d, 4> corner_covariance = {Eigen::Matrix2d::Zero(), Eigen::Matrix2d::Zero(),
                                                      Eigen::Matrix2d::Zero(), Eigen::Matrix2d::Zero()};
  double decision_margin = 0.0;
  int hamming = 0;

  Eigen::Vector2d Center() const;
};

// Whether a tag's corners all lie at least 3 px inside the image's outer
// pixel centres. A tag the border cuts is reported with a corner where it
// cannot be measured (1.7-1.9 px off, reported from 0.4 px beyond to 1.3 px
// inside the border; docs/detection.md), while the edge fit measures a
// whole tag down to 0.4 px from it: 3 px leaves room.
bool ClearOfImageBorder(const std::array<Eigen::Vector2d, 4>& corners, int width, int height);
// The same with any margin (px from the outer pixel centres).
bool WhollyInsideImage(const std::array<Eigen::Vector2d, 4>& corners, int width, int height, double margin_px);

struct DetectionSet {
  FrameId frame = 0;
  std::vector<TagDetection> tags;
};

}  // namespace tagsfm
