#pragma once
// Reading the points of a PLY file (cloud.ply): ascii, binary_little_endian
// or binary_big_endian 1.0; the vertex element's x, y, z of any numeric type,
// in any property order; other properties and elements are skipped.
#include <filesystem>
#include <vector>

#include <Eigen/Core>

#include "tagsfm/core/result.h"

namespace tagsfm::eval {

// A malformed or truncated file is an error naming it and what is wrong.
Result<std::vector<Eigen::Vector3d>> ReadPlyPoints(const std::filesystem::path& path);

}  // namespace tagsfm::eval
