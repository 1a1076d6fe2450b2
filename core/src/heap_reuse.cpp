#include "tagsfm/core/heap_reuse.h"

#include <malloc.h>

namespace tagsfm {

void KeepLargeBlocksForReuse() {
  // Setting the mmap threshold also ends glibc's own adjustment of it; 64
  // MB lies above every image buffer of a 1280x720 keyframe.
  mallopt(M_MMAP_THRESHOLD, 64 << 20);
  mallopt(M_TRIM_THRESHOLD, 256 << 20);
}

}  // namespace tagsfm
