#pragma once
// How the process's heap treats the large blocks that image work allocates
// and frees over and over; set once at the start of a program.

namespace tagsfm {

// Each keyframe's SIFT builds a scale space of tens of blocks of up to 15 MB
// (1280x720 doubled, as floats) and frees it. glibc's defaults hand such
// blocks back to the kernel on every free, and the next keyframe faults the
// pages in again, zeroed: on the 720-frame walk 1.5 million page faults and
// 9 % of the replay's CPU in the kernel. After this call blocks under 64 MB
// come from the heap, and up to 256 MB of free heap is kept for reuse
// (docs/features.md: the replay ~6 % faster, its peak memory ~5 % higher).
void KeepLargeBlocksForReuse();

}  // namespace tagsfm
