#pragma once
// Bundle adjustment of an SfmModel with Ceres: reprojection error in pixels
// (undistorted, the intrinsics held fixed), Huber loss. The gauge is the
// model's: the origin image is held fixed, the scale image's translation
// moves on a sphere (its distance from the origin stays 1).
#include <vector>

#include "tagsfm/core/result.h"
#include "tagsfm/sfm/sfm_model.h"

namespace tagsfm::sfm {

struct BundleOptions {
  double fx = 1000, fy = 1000;  // pixels per normalised unit
  double huber_px = 1.0;
  int max_iterations = 50;
  int threads = 2;
  Status Check() const;
};

struct BundleSummary {
  bool usable = false;
  int images = 0, points = 0, residuals = 0;
  double initial_rms_px = 0, final_rms_px = 0;
};

// Adjusts the images in `variable` (all registered ones when empty) and
// every point they see; other registered images that see those points are
// held fixed.
BundleSummary AdjustBundle(SfmModel* model, const std::vector<ImageIdx>& variable, const BundleOptions& options);

}  // namespace tagsfm::sfm
