#include "tagsfm/analysis/statistics.h"

#include <algorithm>
#include <cmath>

namespace tagsfm::analysis {

Summary Summarize(std::vector<double> values) {
  std::erase_if(values, [](double v) { return !std::isfinite(v); });
  Summary summary;
  summary.count = static_cast<int>(values.size());
  if (values.empty()) return summary;
  double sum = 0, sum_sq = 0;
  for (double v : values) {
    sum += v;
    sum_sq += v * v;
  }
  const double n = static_cast<double>(values.size());
  summary.mean = sum / n;
  summary.rms = std::sqrt(sum_sq / n);
  double deviation_sq = 0;
  for (double v : values) deviation_sq += (v - summary.mean) * (v - summary.mean);
  summary.std = values.size() > 1 ? std::sqrt(deviation_sq / (n - 1)) : 0.0;
  const size_t middle = values.size() / 2;
  std::nth_element(values.begin(), values.begin() + middle, values.end());
  summary.median = values[middle];
  if (values.size() % 2 == 0) {
    summary.median = 0.5 * (summary.median + *std::max_element(values.begin(), values.begin() + middle));
  }
  return summary;
}

}  // namespace tagsfm::analysis
