#pragma once
// Where the feature tracks went (FeatureTriangulationStats), as report.json
// and feature_map_bench write it: per pass, the points and each reason.
#include <nlohmann/json.hpp>

#include "tagsfm/feature/track_triangulation.h"

namespace tagsfm {

nlohmann::json FeatureTriangulationJson(const FeatureTriangulationStats& stats);

}  // namespace tagsfm
