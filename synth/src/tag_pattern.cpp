// Tag bit patterns from libapriltag's own drawing of each code.
#include <apriltag/apriltag.h>
#include <apriltag/common/image_u8.h>
#include <apriltag/tag16h5.h>
#include <apriltag/tag25h9.h>
#include <apriltag/tag36h10.h>
#include <apriltag/tag36h11.h>
#include <apriltag/tagCircle21h7.h>
#include <apriltag/tagCircle49h12.h>
#include <apriltag/tagCustom48h12.h>
#include <apriltag/tagStandard41h12.h>
#include <apriltag/tagStandard52h13.h>

#include <memory>

#include "tagsfm/synth/scene_builder.h"

namespace tagsfm::synth {
namespace {

struct FamilyFns {
  const char* name;
  apriltag_family_t* (*create)();
  void (*destroy)(apriltag_family_t*);
};

constexpr FamilyFns kFamilies[] = {
    {"tag16h5", tag16h5_create, tag16h5_destroy},
    {"tag25h9", tag25h9_create, tag25h9_destroy},
    {"tag36h10", tag36h10_create, tag36h10_destroy},
    {"tag36h11", tag36h11_create, tag36h11_destroy},
    {"tagCircle21h7", tagCircle21h7_create, tagCircle21h7_destroy},
    {"tagCircle49h12", tagCircle49h12_create, tagCircle49h12_destroy},
    {"tagCustom48h12", tagCustom48h12_create, tagCustom48h12_destroy},
    {"tagStandard41h12", tagStandard41h12_create, tagStandard41h12_destroy},
    {"tagStandard52h13", tagStandard52h13_create, tagStandard52h13_destroy},
};

// The family as a handle that destroys itself.
using FamilyPtr = std::unique_ptr<apriltag_family_t, void (*)(apriltag_family_t*)>;

Result<FamilyPtr> CreateFamily(const std::string& family) {
  for (const FamilyFns& f : kFamilies) {
    if (family == f.name) return FamilyPtr(f.create(), f.destroy);
  }
  return MakeError("unknown tag family '" + family + "'");
}

}  // namespace

Result<int> TagFamilySize(const std::string& family) {
  Result<FamilyPtr> fam = CreateFamily(family);
  if (!fam) return fam.error();
  return static_cast<int>((*fam)->ncodes);
}

Result<TagPattern> LoadTagPattern(const std::string& family, TagId id) {
  Result<FamilyPtr> fam = CreateFamily(family);
  if (!fam) return fam.error();
  if (id < 0 || static_cast<uint32_t>(id) >= (*fam)->ncodes) {
    return MakeError("tag id " + std::to_string(id) + " is not in " + family + " (" +
                     std::to_string((*fam)->ncodes) + " codes)");
  }
  image_u8_t* image = apriltag_to_image(fam->get(), id);
  TagPattern pattern;
  pattern.total_width = (*fam)->total_width;
  pattern.width_at_border = (*fam)->width_at_border;
  pattern.white.resize(static_cast<size_t>(pattern.total_width * pattern.total_width));
  for (int row = 0; row < pattern.total_width; ++row) {
    for (int col = 0; col < pattern.total_width; ++col) {
      pattern.white[static_cast<size_t>(row * pattern.total_width + col)] = image->buf[row * image->stride + col] > 127;
    }
  }
  image_u8_destroy(image);
  return pattern;
}

}  // namespace tagsfm::synth
