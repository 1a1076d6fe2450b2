#include "corner_stats.h"

#include <cmath>

namespace tagsfm {

std::map<std::pair<TagId, int>, CornerStats> ComputeCornerStats(const ReconstructionResult& result) {
  std::map<std::pair<TagId, int>, std::pair<double, int>> sums;
  std::map<TagId, TagCorners> corners;
  for (const auto& [id, tag] : result.tags) corners[id] = tag.CornersInWorld();
  for (const auto& frame : result.frames) {
    if (!frame.registered) continue;
    const Rigid3d cam_from_world = frame.cam_from_world.ToRigid();
    for (const auto& obs : frame.tags) {
      auto it = corners.find(obs.id);
      if (it == corners.end()) continue;
      for (int k = 0; k < 4; ++k) {
        auto& [sum, n] = sums[{obs.id, k}];
        sum += (result.camera.Project(cam_from_world * it->second[k]) - obs.pixels[k]).squaredNorm();
        ++n;
      }
    }
  }
  std::map<std::pair<TagId, int>, CornerStats> out;
  for (const auto& [key, sn] : sums) out[key] = {std::sqrt(sn.first / sn.second), sn.second};
  return out;
}

}  // namespace tagsfm
