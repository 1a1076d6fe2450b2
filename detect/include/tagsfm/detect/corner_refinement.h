#pragma once
// Sub-pixel refinement of a detected tag's four outer corners, in OpenCV's
// pixel convention (pixel centres at integers). Both functions start from
// corners good to about a pixel (libapriltag's) and leave them untouched,
// returning false, when the refinement fails or moves a corner implausibly far.
#include <array>

#include <Eigen/Core>
#include <opencv2/core.hpp>

namespace tagsfm {

using QuadCorners = std::array<Eigen::Vector2d, 4>;

// A straight edge n . x = offset, n a unit normal pointing out of the tag.
struct EdgeLine {
  Eigen::Vector2d normal = Eigen::Vector2d::Zero();
  double offset = 0.0;
};

// Fits each of the tag's four outer edges from sub-pixel edge positions
// (gradient-weighted centroids along many normals to the edge, in a window
// re-centred on the fitted line until it is symmetric about it) and
// intersects adjacent lines. modules_across: modules between two corners
// (sets the window so that it stays inside the tag's one-module border).
bool RefineCornersByEdgeLines(const cv::Mat& gray8, int modules_across, QuadCorners* corners);

// OpenCV cornerSubPix on each corner, with a window smaller than one module.
bool RefineCornersBySubPix(const cv::Mat& gray8, int modules_across, QuadCorners* corners);

}  // namespace tagsfm
