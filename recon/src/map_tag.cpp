#include "tagsfm/recon/reconstruction.h"
#include "tagsfm/recon/tag_geometry.h"

namespace tagsfm {

TagCorners MapTag::CornersInWorld() const {
  return known ? known_corners : TagCornersInWorld(world_from_tag.ToRigid(), size_m);
}

PoseMap ReconstructionResult::Poses() const {
  PoseMap poses;
  for (const auto& f : frames) {
    if (f.registered) poses[f.frame] = f.cam_from_world.ToRigid();
  }
  return poses;
}

TargetCornerMap ReconstructionResult::Targets() const {
  TargetCornerMap targets;
  for (const auto& [id, tag] : tags) targets[id] = tag.CornersInWorld();
  return targets;
}

}  // namespace tagsfm
