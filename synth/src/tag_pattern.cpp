// Tag bit patterns from libapriltag's own drawing of each code.
#include <apriltag/apriltag.h>
#include <apriltag/common/image_u8.h>

#include <memory>

#include "tagsfm/detect/apriltag_family.h"
#include "tagsfm/synth/scene_builder.h"

namespace tagsfm::synth {

Result<int> TagFamilySize(const std::string& family) {
  Result<AprilTagFamilyPtr> fam = CreateAprilTagFamily(family);
  if (!fam) return fam.error();
  return static_cast<int>((*fam)->ncodes);
}

Result<TagPattern> LoadTagPattern(const std::string& family, TagId id) {
  Result<AprilTagFamilyPtr> fam = CreateAprilTagFamily(family);
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
