// tagsfm analyze EXPERIMENT --out DIR [--trials N] [--seed S] [--threads T]:
// re-runs one of the paper's synthetic experiments (or `all`) and writes
// DIR/<experiment>.csv (one row per condition and metric: mean, std, median,
// rms, n), DIR/<experiment>.png and the gnuplot script DIR/<experiment>.gp.
#include <filesystem>
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include <spdlog/spdlog.h>

#include "command_registry.h"
#include "tagsfm/analysis/experiments.h"
#include "tagsfm/analysis/plot.h"
#include "tagsfm/core/file_util.h"

namespace tagsfm {
namespace {

struct AnalyzeArgs {
  std::string experiment;
  std::string out_dir;
  analysis::ExperimentOptions options;
  bool compact_plots = false;
};

// Runs one experiment and writes its files; false (after one error line) on failure.
bool RunOne(const std::string& name, const AnalyzeArgs& args, bool& warned_no_gnuplot) {
  Result<analysis::ExperimentResult> result = analysis::RunExperiment(name, args.options);
  if (!result) {
    spdlog::error("{}", result.error().message);
    return false;
  }
  const std::filesystem::path dir(args.out_dir);
  const std::filesystem::path csv_path = dir / (name + ".csv");
  if (Status written = WriteFileAtomically(csv_path, analysis::ToCsv(*result)); !written) {
    spdlog::error("{}", written.error().message);
    return false;
  }
  std::cout << name << ": " << result->rows.size() << " rows, " << result->trials << " trials, "
            << result->runtime_s << " s -> " << csv_path.string();
  const std::filesystem::path image_path = dir / (name + ".png");
  Result<analysis::PlotOutcome> plotted = analysis::RenderPlot(
      *result, image_path, args.compact_plots ? analysis::PlotFormat::kCompact : analysis::PlotFormat::kCairo);
  if (!plotted) {
    std::cout << std::endl;
    spdlog::error("{}", plotted.error().message);
    return false;
  }
  if (*plotted == analysis::PlotOutcome::kWritten) std::cout << ", " << image_path.string();
  std::cout << std::endl;
  if (*plotted == analysis::PlotOutcome::kGnuplotMissing && !warned_no_gnuplot) {
    std::cout << "gnuplot not found: plots skipped (install gnuplot-nox; the CSV files are complete)" << std::endl;
    warned_no_gnuplot = true;
  }
  for (const std::string& note : result->notes) std::cout << "  note: " << note << "\n";
  return true;
}

int RunAnalyze(const AnalyzeArgs& args) {
  std::vector<std::string> names;
  for (const analysis::ExperimentInfo& info : analysis::ExperimentCatalogue()) {
    if (args.experiment == "all" || args.experiment == info.name) names.push_back(info.name);
  }
  if (names.empty()) names.push_back(args.experiment);  // RunExperiment names the known ones
  if (Status ok = args.options.Check(); !ok) {
    spdlog::error("{}", ok.error().message);
    return 2;
  }
  std::error_code ec;
  std::filesystem::create_directories(args.out_dir, ec);
  if (ec) {
    spdlog::error("--out {}: cannot create the directory: {}", args.out_dir, ec.message());
    return 1;
  }
  bool warned_no_gnuplot = false;
  for (const std::string& name : names) {
    if (!RunOne(name, args, warned_no_gnuplot)) return 1;
  }
  return 0;
}

std::string ExperimentHelp() {
  std::string help = "experiment to run, or `all`:";
  for (const analysis::ExperimentInfo& info : analysis::ExperimentCatalogue()) {
    help += "\n  " + info.name + " (" + info.paper_section + "): " + info.summary + " [default trials " +
            std::to_string(info.default_trials) + " " + info.trial_unit + "]";
  }
  return help;
}

void AddAnalyzeCommand(CLI::App& app, int& exit_code) {
  auto args = std::make_shared<AnalyzeArgs>();
  CLI::App* cmd = app.add_subcommand("analyze", "re-run one of the paper's synthetic experiments (section 4.1-4.2); "
                                                "writes CSV and plots");
  cmd->add_option("experiment", args->experiment, ExperimentHelp())->required();
  cmd->add_option("--out", args->out_dir, "output directory (created if missing)")->required();
  cmd->add_option("--trials", args->options.trials, "Monte-Carlo trials per condition (0: the experiment's default)")
      ->capture_default_str();
  cmd->add_option("--seed", args->options.seed, "random seed (same seed, same numbers)")->capture_default_str();
  cmd->add_option("--threads", args->options.threads, "worker threads (0: all cores)")->capture_default_str();
  cmd->add_flag("--compact-plots", args->compact_plots,
                "palette PNGs (gnuplot's png terminal), ~5x smaller than the default anti-aliased pngcairo");
  cmd->callback([args, &exit_code] { exit_code = RunAnalyze(*args); });
}

const bool kRegistered = RegisterCommand("analyze", &AddAnalyzeCommand);

}  // namespace
}  // namespace tagsfm
