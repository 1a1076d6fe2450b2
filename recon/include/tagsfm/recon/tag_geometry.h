#pragma once
// A square tag as a rigid body: its pose world_from_tag and its known edge
// length fix all four corners exactly. The tag frame has x to the right and
// y up on the printed tag seen from the front, z out of the printed face, so
// libapriltag's corner order (bottom-left, bottom-right, top-right, top-left)
// is (-h,-h), (h,-h), (h,h), (-h,h) with h = size / 2.
#include <array>
#include <optional>

#include <Eigen/Core>

#include "tagsfm/core/csv_formats.h"
#include "tagsfm/core/rigid3d.h"

namespace tagsfm {

// Corner k of a tag of edge `size_m`, in the tag's own frame.
Eigen::Vector3d TagCornerInTag(int corner, double size_m);
TagCorners TagCornersInTag(double size_m);

// world_from_tag applied to the four corners.
TagCorners TagCornersInWorld(const Rigid3d& world_from_tag, double size_m);

// The square pose that best fits four measured corners (least squares,
// rotation and translation only: the size stays the one given).
Rigid3d FitTagPose(const TagCorners& corners_in_world, double size_m);

// Mean of the four corners.
Eigen::Vector3d TagCenter(const TagCorners& corners);

// The four edge lengths 0-1, 1-2, 2-3, 3-0.
std::array<double, 4> TagEdgeLengths(const TagCorners& corners);

}  // namespace tagsfm
