#pragma once
// Per-corner reprojection figures of a result, for cloud.ply and
// colmap/points3D.txt: RMS error (px) and number of frames, keyed by
// (tag, corner).
#include <map>
#include <utility>

#include "tagsfm/recon/reconstruction.h"

namespace tagsfm {

struct CornerStats {
  double rms_px = 0;
  int track_length = 0;
};
std::map<std::pair<TagId, int>, CornerStats> ComputeCornerStats(const ReconstructionResult& result);

}  // namespace tagsfm
