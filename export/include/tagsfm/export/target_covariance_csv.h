#pragma once
// targets_cov.csv: the learned targets' joint 6-DoF pose covariance, one row
// per pair of tags (a <= b) with the 36 entries of their 6x6 block, so that
// `tagsfm measure` can give distances between targets with their deviation.
#include <filesystem>

#include "tagsfm/core/result.h"
#include "tagsfm/recon/reconstruction.h"

namespace tagsfm {

Status WriteTargetCovariance(const std::filesystem::path& path, const TagCovariance& covariance);
Result<TagCovariance> ReadTargetCovariance(const std::filesystem::path& path);

}  // namespace tagsfm
