#include "tagsfm/analysis/experiment_result.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace tagsfm::analysis {
namespace {

std::string FormatNumber(double value) {
  char buffer[32];
  std::snprintf(buffer, sizeof(buffer), "%.6g", value);
  return buffer;
}

}  // namespace

std::vector<const ConditionRow*> ExperimentResult::Line(const Panel& panel, const std::string& series) const {
  std::vector<const ConditionRow*> line;
  for (const ConditionRow& row : rows) {
    if (row.object == panel.object && row.facet == panel.facet && row.metric == panel.metric && row.series == series) {
      line.push_back(&row);
    }
  }
  std::stable_sort(line.begin(), line.end(), [](const ConditionRow* a, const ConditionRow* b) { return a->x < b->x; });
  return line;
}

std::vector<std::string> ExperimentResult::SeriesInOrder() const {
  std::vector<std::string> series;
  for (const ConditionRow& row : rows) {
    if (std::find(series.begin(), series.end(), row.series) == series.end()) series.push_back(row.series);
  }
  return series;
}

const ConditionRow* ExperimentResult::Find(const std::string& object, const std::string& series, double x,
                                           const std::string& metric) const {
  for (const ConditionRow& row : rows) {
    if (row.object == object && row.series == series && std::abs(row.x - x) <= 1e-9 * std::max(1.0, std::abs(x)) &&
        row.metric == metric) {
      return &row;
    }
  }
  return nullptr;
}

std::string ToCsv(const ExperimentResult& result) {
  const bool with_facet = !result.facet_column.empty();
  std::string csv = "object," + (with_facet ? result.facet_column + "," : std::string()) + result.series_column + "," + result.x_column + ",metric,mean,std,median,rms,n\n";
  for (const ConditionRow& row : result.rows) {
    csv += row.object + "," + (with_facet ? row.facet + "," : std::string()) + row.series + "," + FormatNumber(row.x) + "," + row.metric + "," +
           FormatNumber(row.stats.mean) + "," + FormatNumber(row.stats.std) + "," + FormatNumber(row.stats.median) +
           "," + FormatNumber(row.stats.rms) + "," + std::to_string(row.stats.count) + "\n";
  }
  return csv;
}

}  // namespace tagsfm::analysis
