#pragma once
// Matching two keyframes whose poses are known (from the targets): a
// feature of the first can only match a feature of the second near the
// segment of its epipolar line between the projections of its ray at the
// scene's near and far depth. Among those candidates, Lowe's ratio test on
// both sides and a mutual best match; no RANSAC, the poses are the model.
#include <vector>

#include <Eigen/Core>

#include "tagsfm/core/camera_model.h"
#include "tagsfm/core/result.h"
#include "tagsfm/core/rigid3d.h"
#include "tagsfm/feature/feature_extractor.h"

namespace tagsfm {

// Depths (along the optical axis, metres) between which the scene in view
// lies, e.g. from the targets in view.
struct DepthRange {
  double near_m = 0;
  double far_m = 0;

  // `depth_m` divided and multiplied by `factor` (> 1).
  static DepthRange Around(double depth_m, double factor);
  double Typical() const;  // the geometric mean of near and far
  Status Check() const;    // 0 < near < far, finite
};

// A keyframe ready for matching: its features, pose, depth range and the
// features' undistorted pixels (the pinhole image of the same camera, where
// epipolar lines are straight).
struct PosedKeyframe {
  KeyframeFeatures features;
  Rigid3d cam_from_world;
  DepthRange depth;
  std::vector<Eigen::Vector2d> undistorted;  // fx x + cx, fy y + cy of the normalised point
};

Result<PosedKeyframe> MakePosedKeyframe(KeyframeFeatures features, const Rigid3d& cam_from_world, const DepthRange& depth,
                                        const CameraModel& camera);

struct GuidedMatcherOptions {
  // Largest distance of a match from the epipolar segment, undistorted
  // pixels: feature localisation, pose and lens-model errors together.
  double epipolar_px = 2.0;
  double ratio = 0.8;                   // best / second-best descriptor distance, on both sides
  double max_descriptor_distance = 0.7; // L2 between unit descriptors (0.7: ~40 degrees apart)
  int grid_cell_px = 12;                // bucket size of the second image's features (measured in docs/features.md)

  Status Check() const;  // names the wrong field
};

struct FeatureMatch {
  int first = -1;   // feature index in the first keyframe
  int second = -1;  // in the second
  float descriptor_distance = 0;
};

struct GuidedMatches {
  std::vector<FeatureMatch> matches;
  long long candidates = 0;  // feature pairs on an epipolar segment (descriptor comparisons)
};

// Ratio test and mutual best among the pairs (i, j) where j lies within
// epipolar_px of the segment of i's epipolar line between `first.depth`'s
// near and far. Both keyframes from the same camera.
GuidedMatches MatchGuided(const PosedKeyframe& first, const PosedKeyframe& second, const CameraModel& camera,
                          const GuidedMatcherOptions& options);

}  // namespace tagsfm
