#pragma once
// A result against the truth of a synthetic recording: the target corners
// after a rigid alignment (rotation and translation only, so the scale must
// already be right), the scale a similarity alignment would need, and each
// camera's rotation and centre error once brought into the truth's frame.
// The fits are EstimateSim3d's (similarity.h).
#include "tagsfm/core/csv_formats.h"

namespace tagsfm::eval {

struct TruthComparison {
  int targets_compared = 0;
  double corner_rms_m = 0;          // after the rigid alignment
  double scene_size_m = 0;          // diagonal of the true targets' bounding box
  double scale = 1;                 // similarity alignment's scale (1 = metric)
  int frames_compared = 0, frames_in_truth = 0;
  double rotation_median_deg = 0, rotation_max_deg = 0;
  double centre_median_m = 0, centre_max_m = 0;
};

// `align_world`: align the estimated world to the truth through the targets
// (a map built without one); false when the estimate is in the truth's frame
// already (a known map was given).
TruthComparison CompareWithTruth(const PoseMap& poses, const TargetCornerMap& targets, const PoseMap& true_poses,
                                 const TargetCornerMap& true_targets, bool align_world);

}  // namespace tagsfm::eval
