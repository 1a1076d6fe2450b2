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

struct TagLayout;
struct CameraModel;

// Fits each of the tag's four outer edges and intersects adjacent lines.
// Each edge is fitted by Gauss-Newton to the pixels of a band around it,
// with a model of the blurred step plus the blurred modules behind the
// border that have the outside's shade (from the layout: on small, blurred
// tags that inner edge, one module in, otherwise pulls the edge outward by up
// to 0.1 px) and the adjacent edges near the corners. Outside, the band
// stays within one module of the edge, the white a tag has at the least
// (libapriltag's images printed edge to edge); beyond that ring the model
// has a level of its own (texture, another tag, the sheet's edge), which
// does not place the edge. Unknown layout (empty like_border): a plain
// blurred step (and the adjacent edges).
//
// `camera` (optional, may be null): the image's camera model. With lens
// distortion the edges are straight only in undistorted coordinates, and a
// line fitted to distorted pixels carries the edge's sagitta (~0.01-0.03 px
// on a 24 px tag near the border of a typical wide lens): the band's pixels
// are then mapped to undistorted pixel coordinates (the same K, no
// distortion), the lines fitted and intersected there, and the corners
// mapped back through the distortion. `corners` are image pixels either way.
// Without distortion the camera changes nothing.
//
// `covariances` (optional): each corner's 2x2 covariance in image pixels,
// from the two edges' fits (the inverse normal matrix times the residuals'
// variance, through the lines' intersection and the lens): what the corner
// is worth, larger on small, blurred, noisy or strongly tilted tags. Zero
// where a fit gave no covariance.
bool RefineCornersByEdgeLines(const cv::Mat& gray8, const TagLayout& layout, QuadCorners* corners,
                              const CameraModel* camera = nullptr,
                              std::array<Eigen::Matrix2d, 4>* covariances = nullptr);

// OpenCV cornerSubPix on each corner, with a window smaller than one module.
bool RefineCornersBySubPix(const cv::Mat& gray8, int modules_across, QuadCorners* corners);

}  // namespace tagsfm
