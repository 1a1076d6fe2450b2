#pragma once
// libapriltag's tag families by name, owned with their matching destroy
// function (each family has its own create/destroy pair in libapriltag).
// Public so that everything drawing or decoding tags (detect, synth) shares
// one table of the families tagsfm knows.
#include <memory>
#include <string>

#include <apriltag/apriltag.h>

#include "tagsfm/core/result.h"

namespace tagsfm {

struct AprilTagFamilyDeleter {
  void (*destroy)(apriltag_family_t*) = nullptr;
  void operator()(apriltag_family_t* family) const {
    if (family != nullptr && destroy != nullptr) destroy(family);
  }
};
using AprilTagFamilyPtr = std::unique_ptr<apriltag_family_t, AprilTagFamilyDeleter>;

// A fresh family instance (libapriltag keeps per-detector decode tables in a
// family, so one instance serves one detector). Unknown name: an error that
// names the field and lists the known families.
Result<AprilTagFamilyPtr> CreateAprilTagFamily(const std::string& name);

}  // namespace tagsfm
