#include "tagsfm/export/feature_triangulation_json.h"

namespace tagsfm {

namespace {

nlohmann::json PassJson(const TrackTriangulationStats& s) {
  return {{"tracks", s.tracks},
          {"points", s.points},
          {"too_few_views", s.too_few_views},
          {"no_linear_point", s.no_linear_point},
          {"reprojection", s.reprojection},
          {"narrow_angle", s.narrow_angle},
          {"predicted_sigma", s.predicted_sigma}};
}

}  // namespace

nlohmann::json FeatureTriangulationJson(const FeatureTriangulationStats& stats) {
  return {{"first_pass", PassJson(stats.first_pass)},
          {"epipolar_sigma_px", stats.epipolar_sigma_px},
          {"max_fit_sigma_px", stats.max_fit_sigma_px},
          {"line_fits", stats.line_fits},
          {"tilted_fits", stats.tilted_fits},
          {"refinement_dropped", stats.refinement_dropped},
          {"final_pass", PassJson(stats.final_pass)}};
}

}  // namespace tagsfm
