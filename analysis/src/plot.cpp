#include "tagsfm/analysis/plot.h"

#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>

#include <cerrno>
#include <algorithm>
#include <cmath>
#include <cstring>
#include <sstream>

#include "tagsfm/core/file_util.h"

extern char** environ;

namespace tagsfm::analysis {
namespace {

// A gnuplot double-quoted string.
std::string Quoted(const std::string& text) {
  std::string out = "\"";
  for (char c : text) {
    if (c == '"' || c == '\\') out += '\\';
    out += c;
  }
  return out + "\"";
}

std::string Substitute(std::string format, const std::string& value) {
  const size_t at = format.find("%s");
  return at == std::string::npos ? value : format.replace(at, 2, value);
}

double StatisticOf(const ConditionRow& row, Statistic statistic) {
  switch (statistic) {
    case Statistic::kMean: return row.stats.mean;
    case Statistic::kStd: return row.stats.std;
    case Statistic::kMedian: return row.stats.median;
    case Statistic::kRms: return row.stats.rms;
  }
  return row.stats.mean;
}

const char* StatisticName(Statistic statistic) {
  switch (statistic) {
    case Statistic::kMean: return "mean";
    case Statistic::kStd: return "standard deviation";
    case Statistic::kMedian: return "median";
    case Statistic::kRms: return "RMS";
  }
  return "";
}

// Fixed colours per series, so a series keeps its colour in every panel even
// when a log axis leaves one out (colour-blind-safe first eight, Okabe-Ito).
const char* SeriesColour(size_t index) {
  static const char* kColours[] = {"#000000", "#E69F00", "#56B4E9", "#009E73", "#D55E00", "#0072B2",
                                   "#CC79A7", "#F0E442", "#7F7F7F", "#8C564B", "#17BECF", "#BCBD22"};
  return kColours[index % (sizeof(kColours) / sizeof(kColours[0]))];
}

// On a log axis, values this far below the panel's largest median are zero
// up to rounding (e.g. the error at zero noise) and are left out.
constexpr double kNumericalZeroRatio = 1e-4;

void WritePanel(const ExperimentResult& result, const Panel& panel, int panel_index, std::ostringstream& script) {
  std::vector<std::string> plots;
  const std::vector<std::string> all_series = result.SeriesInOrder();
  // A few wild EPnP solutions (e.g. 5 nearly coplanar points) can put a mean
  // 1e40 above the rest; cap a log axis at 30x the largest median so the
  // other lines stay readable (the CSV keeps every value).
  double largest_median = 0, largest_value = 0;
  for (const std::string& series : all_series) {
    for (const ConditionRow* row : result.Line(panel, series)) {
      if (row->stats.count == 0) continue;
      largest_median = std::max(largest_median, row->stats.median);
      largest_value = std::max(largest_value, StatisticOf(*row, panel.statistic));
    }
  }
  const double y_cap = 30.0 * largest_median;
  const bool capped = panel.log_y && panel.statistic != Statistic::kMedian && largest_value > y_cap && y_cap > 0;
  for (size_t series_index = 0; series_index < all_series.size(); ++series_index) {
    const std::string& series = all_series[series_index];
    std::ostringstream block;
    int points = 0;
    for (const ConditionRow* row : result.Line(panel, series)) {
      const double y = StatisticOf(*row, panel.statistic);
      // A log axis cannot show zero (e.g. the error at zero noise): leave it out.
      if (!std::isfinite(y) || (panel.log_y && y <= kNumericalZeroRatio * largest_median) || row->stats.count == 0) continue;
      block << row->x << " " << y << "\n";
      ++points;
    }
    if (points == 0) continue;
    const std::string name = "$p" + std::to_string(panel_index) + "s" + std::to_string(plots.size());
    script << name << " << EOD\n" << block.str() << "EOD\n";
    plots.push_back(name + " using 1:2 with linespoints lw 1.5 pt 7 ps 0.5 lc rgb \"" + SeriesColour(series_index) +
                    "\" title " + Quoted(Substitute(result.series_legend, series)));
  }
  const std::string facet = panel.facet.empty() ? "" : ", " + Substitute(result.facet_title, panel.facet);
  script << "set title " << Quoted(panel.object + facet + ": " + StatisticName(panel.statistic) +
                                   (capped ? " (capped axis)" : ""))
         << "\n";
  script << "set xlabel " << Quoted(result.x_label) << "\nset ylabel " << Quoted(panel.y_label) << "\n";
  script << (result.log_x ? "set logscale x\n" : "unset logscale x\n");
  if (plots.empty()) {  // gnuplot refuses a plot whose points are all undefined
    script << "unset logscale y\nset label 1 \"no data\" at graph 0.5,0.5 center\nplot [0:1] [0:1] -1 notitle\n"
              "unset label 1\n";
    return;
  }
  script << (panel.log_y ? "set logscale y\nset format y \"%g\"\n" : "unset logscale y\nset format y \"%g\"\n");
  if (capped) {
    script << "set yrange [*:" << y_cap << "]\n";
  } else if (panel.metric.ends_with("_rate")) {  // a fraction
    script << "set yrange [0:1]\n";
  } else {
    script << "set yrange [*:*]\n";
  }
  script << "plot ";
  for (size_t i = 0; i < plots.size(); ++i) script << (i ? ", \\\n     " : "") << plots[i];
  script << "\n";
}

}  // namespace

std::string GnuplotScript(const ExperimentResult& result, const std::filesystem::path& image_path, PlotFormat format) {
  const int columns = std::max(1, result.panel_columns);
  const int rows = (static_cast<int>(result.panels.size()) + columns - 1) / columns;
  std::ostringstream script;
  script << "# " << result.name << ": generated by `tagsfm analyze`; render with `gnuplot " << result.name << ".gp`\n";
  script << (format == PlotFormat::kCairo ? "set terminal pngcairo noenhanced size " : "set terminal png noenhanced size ")
         << 620 * columns << "," << 400 * rows + 40
         << (format == PlotFormat::kCairo ? " font \"DejaVu Sans,10\"\n" : " font \"DejaVuSans,9\"\n");
  script << "set output " << Quoted(image_path.string()) << "\n";
  script << "set grid\nset key outside right top vertical font \",8\"\nset autoscale xfix\n";
  script << "set multiplot layout " << rows << "," << columns << " title " << Quoted(result.title)
         << " font \",12\"\n";
  for (size_t i = 0; i < result.panels.size(); ++i) WritePanel(result, result.panels[i], static_cast<int>(i), script);
  script << "unset multiplot\nset output\n";
  return script.str();
}

Result<PlotOutcome> RenderPlot(const ExperimentResult& result, const std::filesystem::path& image_path,
                               PlotFormat format) {
  return RenderGnuplot([&](const std::filesystem::path& output) { return GnuplotScript(result, output, format); },
                       image_path);
}

Result<PlotOutcome> RenderGnuplot(const std::function<std::string(const std::filesystem::path&)>& script_for,
                                  const std::filesystem::path& image_path) {
  std::filesystem::path script_path = image_path;
  script_path.replace_extension(".gp");
  std::filesystem::path log_path = image_path;
  log_path.replace_extension(".gnuplot.log");
  // gnuplot writes to a temporary name that is renamed into place, so a reader never sees half an image.
  const std::filesystem::path temporary_image = image_path.string() + ".tmp";
  if (Status written = WriteFileAtomically(script_path, script_for(image_path)); !written) {
    return written.error();
  }
  const std::string render_script = script_for(temporary_image);
  const std::filesystem::path render_path = script_path.string() + ".tmp";
  if (Status written = WriteFileAtomically(render_path, render_script); !written) return written.error();

  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, log_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_adddup2(&actions, STDOUT_FILENO, STDERR_FILENO);
  std::string program = "gnuplot";
  std::string script_arg = render_path.string();
  char* argv[] = {program.data(), script_arg.data(), nullptr};
  pid_t pid = 0;
  const int spawn_error = posix_spawnp(&pid, "gnuplot", &actions, nullptr, argv, environ);
  posix_spawn_file_actions_destroy(&actions);
  std::error_code ignored;
  if (spawn_error == ENOENT) {
    std::filesystem::remove(render_path, ignored);
    std::filesystem::remove(log_path, ignored);
    return PlotOutcome::kGnuplotMissing;
  }
  if (spawn_error != 0) return MakeError("cannot run gnuplot: " + std::string(std::strerror(spawn_error)));
  int status = 0;
  while (waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  std::filesystem::remove(render_path, ignored);
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0 || !std::filesystem::exists(temporary_image)) {
    std::filesystem::remove(temporary_image, ignored);
    return MakeError("gnuplot failed on " + script_path.string() + " (see " + log_path.string() + ")");
  }
  std::filesystem::rename(temporary_image, image_path, ignored);
  if (ignored) return MakeError("cannot rename " + temporary_image.string() + ": " + ignored.message());
  std::filesystem::remove(log_path, ignored);
  return PlotOutcome::kWritten;
}

}  // namespace tagsfm::analysis
