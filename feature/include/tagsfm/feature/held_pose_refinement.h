#pragma once
// Feature points refined one by one with the poses and the camera held:
// the points that the joint adjustment of poses and points leaves out (its
// tie points are a sample; Reconstructor::AdjustWithPoints) take the same
// Huber-weighted reprojection error's minimum on the poses it adjusted.
// Each point is its own 3-unknown problem, so any number of threads gives
// the same points.
#include <cstddef>
#include <vector>

#include "tagsfm/core/camera_model.h"
#include "tagsfm/core/csv_formats.h"
#include "tagsfm/core/rigid3d.h"
#include "tagsfm/feature/feature_triangulation.h"

namespace tagsfm {

struct HeldPoseRefinementOptions {
  double huber_px = 1.0;    // the robust loss' scale, in pixels
  int max_iterations = 10;  // Gauss-Newton steps (a point starts at its triangulation)
  int threads = 2;
};

// Moves points[i].position for every i of `which` (a point that is behind
// one of its cameras keeps its position). Views of frames missing from
// `cam_from_world` are left out of its error.
void RefinePointsOnHeldPoses(const PoseMap& cam_from_world, const CameraModel& camera,
                             const HeldPoseRefinementOptions& options, const std::vector<size_t>& which,
                             std::vector<FeaturePoint>* points);

}  // namespace tagsfm
