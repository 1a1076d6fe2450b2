// The covariance of a global adjustment's learned tags (and intrinsics),
// computed from the solved problem's Jacobian.
#pragma once

#include <vector>

#include <ceres/ceres.h>

#include "tagsfm/recon/bundle_adjuster.h"

namespace tagsfm {

// Fills out->covariance (the learned tags', 6 per tag in id order) and, when
// `intrinsics` is a block of the problem, out->intrinsics_covariance, or
// out->covariance_note with why not. `points`: the feature points adjusted
// with them (null for a targets-only adjustment); their rays then inform the
// tags' covariance as they informed the tags. The covariance is scaled by
// the a posteriori variance of the targets' residuals: the problem's first
// `target_residuals` residuals, with `target_parameters` unknowns (the
// cameras', the learned tags', the intrinsics').
void ComputeCovariance(ceres::Problem* problem, const std::vector<FrameState*>& frames, std::map<TagId, MapTag>* tags,
                       double* intrinsics, const std::vector<AdjustedPoint>* points, int target_residuals,
                       int target_parameters, GlobalAdjustmentSummary* out);

}  // namespace tagsfm
