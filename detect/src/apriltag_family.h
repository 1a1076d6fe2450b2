#pragma once
// libapriltag's tag families by name, owned with their matching destroy
// function (each family has its own create/destroy pair in libapriltag).
#include <memory>
#include <string>

#include <apriltag/apriltag.h>

#include "tagsfm/core/result.h"
#include "tagsfm/detect/tag_layout.h"

namespace tagsfm::detail {

struct FamilyDeleter {
  void (*destroy)(apriltag_family_t*) = nullptr;
  void operator()(apriltag_family_t* family) const {
    if (family != nullptr && destroy != nullptr) destroy(family);
  }
};
using FamilyPtr = std::unique_ptr<apriltag_family_t, FamilyDeleter>;

// A fresh family instance (libapriltag keeps per-detector decode tables in a
// family, so one instance serves one detector). Unknown name: an error.
Result<FamilyPtr> CreateAprilTagFamily(const std::string& name);

// The module layout of code `id` (0 <= id < ncodes) of the family.
TagLayout LayoutOf(apriltag_family_t* family, TagId id);

}  // namespace tagsfm::detail
