// Length errors between tag pairs and the map's precision as a fraction of
// the scene (see evaluation.h): what an acceptance test of a measuring
// system reports, beside the paper's pose errors.
#include <algorithm>
#include <cmath>

#include "tagsfm/eval/evaluation.h"
#include "tagsfm/recon/tag_geometry.h"

namespace tagsfm::eval {

LengthErrors CompareLengths(const TargetCornerMap& truth, const TargetCornerMap& estimate,
                            const std::optional<TagCovariance>& covariance, double scale_sigma_rel) {
  TargetCornerMap common;
  for (const auto& [id, corners] : estimate) {
    if (truth.count(id)) common.emplace(id, corners);
  }
  LengthErrors out;
  std::vector<double> abs_errors, normalized;
  double sum_el = 0, sum_ll = 0;
  double weighted_el = 0, weighted_ll = 0;
  for (const TagPairMeasurement& p : MeasureAllTagPairs(common, covariance, scale_sigma_rel)) {
    LengthError e;
    e.a = p.a;
    e.b = p.b;
    e.measured_length_m = p.measurement.distance_m;
    e.true_length_m = (TagCenter(truth.at(p.a)) - TagCenter(truth.at(p.b))).norm();
    e.error_m = e.measured_length_m - e.true_length_m;
    e.sigma_m = p.measurement.sigma_m;
    abs_errors.push_back(std::abs(e.error_m));
    if (e.sigma_m && *e.sigma_m > 0) normalized.push_back(e.error_m / *e.sigma_m);
    sum_el += e.error_m * e.true_length_m;
    sum_ll += e.true_length_m * e.true_length_m;
    if (e.sigma_m) {
      // The covariance's own variance: the scale term went in in quadrature.
      const double scale_part = scale_sigma_rel * e.measured_length_m;
      const double variance = *e.sigma_m * *e.sigma_m - scale_part * scale_part;
      if (variance > 0) {
        weighted_el += e.error_m * e.true_length_m / variance;
        weighted_ll += e.true_length_m * e.true_length_m / variance;
      }
    }
    out.pairs.push_back(e);
  }
  out.abs_error_m = Stats::Of(abs_errors);
  out.error_per_length_ppm = sum_ll > 0 ? sum_el / sum_ll * 1e6 : 0.0;
  if (weighted_ll > 0) out.weighted_error_per_length_ppm = weighted_el / weighted_ll * 1e6;
  out.normalized_count = static_cast<int>(normalized.size());
  if (!normalized.empty()) {
    double sum = 0, sum_sq = 0;
    int beyond = 0;
    for (double r : normalized) {
      sum += r;
      beyond += std::abs(r) > 3 ? 1 : 0;
    }
    out.normalized_mean = sum / normalized.size();
    for (double r : normalized) sum_sq += (r - out.normalized_mean) * (r - out.normalized_mean);
    out.normalized_std = normalized.size() > 1 ? std::sqrt(sum_sq / (normalized.size() - 1)) : 0.0;
    out.beyond_3_sigma = static_cast<double>(beyond) / normalized.size();
  }
  return out;
}

}  // namespace tagsfm::eval
