#pragma once
// Comparing a reconstruction with the truth: the rigid (or similarity)
// transform that best maps estimated points onto true ones.
#include <vector>

#include <Eigen/Core>

#include "tagsfm/core/rigid3d.h"

namespace tagsfm {

struct Alignment {
  Rigid3d truth_from_estimate;
  double scale = 1.0;      // 1 for a rigid alignment
  double rms_m = 0;        // of the aligned points
};

// Least squares (Kabsch/Umeyama); with_scale estimates a scale as well.
// Needs at least 3 non-collinear pairs.
Alignment AlignPoints(const std::vector<Eigen::Vector3d>& estimate, const std::vector<Eigen::Vector3d>& truth,
                      bool with_scale);

}  // namespace tagsfm
