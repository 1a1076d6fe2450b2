#pragma once
// A tag's corner square as a grid of modules, and the homography that maps it
// into an image: what the corner refinement needs to know about the tag.
#include <array>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "tagsfm/core/result.h"
#include "tagsfm/detect/corner_refinement.h"
#include "tagsfm/detect/tag_detection.h"

namespace tagsfm {

// Corner-square coordinates: modules, x right, y down, origin at the square's
// top-left; libapriltag's corners 0..3 sit at (0, n), (n, n), (n, 0), (0, 0).
struct TagLayout {
  int modules_across = 0;
  // Row-major n x n: true where the module has the border's shade. Empty when
  // the pattern is unknown.
  std::vector<bool> like_border;

  bool LikeBorder(int col, int row) const {
    return col >= 0 && row >= 0 && col < modules_across && row < modules_across &&
           like_border[static_cast<size_t>(row * modules_across + col)];
  }
};

// The layout of tag `id` of a libapriltag family.
Result<TagLayout> MakeTagLayout(const std::string& family, TagId id);

// libapriltag's corners 0..3 in corner-square coordinates.
QuadCorners CornerSquareCorners(int modules_across);

// The homography mapping the four `from` points onto `to`, exactly (double
// precision); none when three of them are collinear.
std::optional<Eigen::Matrix3d> HomographyFrom4(const QuadCorners& from, const QuadCorners& to);

}  // namespace tagsfm
