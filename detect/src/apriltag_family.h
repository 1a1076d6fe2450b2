#pragma once
// detect's private view of the family table (tagsfm/detect/apriltag_family.h)
// plus the module layout of a code, which only the detector needs.
#include <apriltag/apriltag.h>

#include "tagsfm/detect/apriltag_family.h"
#include "tagsfm/detect/tag_layout.h"

namespace tagsfm::detail {

using FamilyPtr = AprilTagFamilyPtr;
using tagsfm::CreateAprilTagFamily;

// The module layout of code `id` (0 <= id < ncodes) of the family.
TagLayout LayoutOf(apriltag_family_t* family, TagId id);

}  // namespace tagsfm::detail
