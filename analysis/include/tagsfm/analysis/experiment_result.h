#pragma once
// What an experiment produces: one summary per condition and metric (a tidy
// table, written as CSV), and how to draw it (panels of the figure).
#include <string>
#include <vector>

#include "tagsfm/analysis/statistics.h"

namespace tagsfm::analysis {

struct ConditionRow {
  std::string object;  // scene, e.g. "box", "bradley-like"
  std::string facet;   // a third variable drawn in separate panels (empty if none), e.g. "1" px
  std::string series;  // the value of the line's variable, e.g. "2" (px) or "clustered"
  double x = 0;        // the x axis' variable, e.g. camera depth
  std::string metric;  // with its unit, e.g. "positional_error_units"; "*_rate" metrics are fractions 0-1
  Summary stats;
};

enum class Statistic { kMean, kStd, kMedian, kRms };

// One panel of the figure: one line per series, `statistic` of `metric` against x.
struct Panel {
  std::string object;
  std::string facet;
  std::string metric;
  Statistic statistic = Statistic::kMean;
  std::string y_label;
  bool log_y = false;
};

struct ExperimentResult {
  std::string name;           // "depth-image-noise"
  std::string title;          // figure title
  std::string facet_column;   // CSV column of `facet`; empty: no such column
  std::string facet_title;    // panel title part, "%s" replaced by the facet, e.g. "σ = %s px"
  std::string series_column;  // CSV column of `series`, e.g. "image_noise_px"
  std::string series_legend;  // legend format, "%s" replaced by the series, e.g. "σ = %s px"
  std::string x_column;       // CSV column of `x`, e.g. "depth"
  std::string x_label;        // axis label with unit
  bool log_x = false;
  std::vector<ConditionRow> rows;
  std::vector<Panel> panels;
  int panel_columns = 2;
  std::vector<std::string> notes;  // set-up details and deviations from the paper, for the console and docs
  int trials = 0;                  // as run
  double runtime_s = 0;

  // Rows of one panel's line, in x order.
  std::vector<const ConditionRow*> Line(const Panel& panel, const std::string& series) const;
  std::vector<std::string> SeriesInOrder() const;  // as first seen
  const ConditionRow* Find(const std::string& object, const std::string& series, double x,
                           const std::string& metric) const;
};

// object,[<facet_column>,]<series_column>,<x_column>,metric,mean,std,median,rms,n
std::string ToCsv(const ExperimentResult& result);

}  // namespace tagsfm::analysis
