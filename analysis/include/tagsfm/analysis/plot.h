#pragma once
// Figures with gnuplot (Debian's gnuplot-nox): a generated script with the
// data inline, rendered by the gnuplot executable to PNG (pngcairo). The
// script is kept beside the image so a reader can restyle and re-render it.
#include <filesystem>
#include <string>

#include "tagsfm/analysis/experiment_result.h"
#include "tagsfm/core/result.h"

namespace tagsfm::analysis {

// The gnuplot script that draws `result` into `image_path` (one panel per
// Panel, one line per series, like the paper's figures).
std::string GnuplotScript(const ExperimentResult& result, const std::filesystem::path& image_path);

enum class PlotOutcome { kWritten, kGnuplotMissing };

// Writes `<image_path without extension>.gp` and runs gnuplot on it. An error
// when gnuplot runs but fails (its messages are in `<stem>.gnuplot.log`).
Result<PlotOutcome> RenderPlot(const ExperimentResult& result, const std::filesystem::path& image_path);

}  // namespace tagsfm::analysis
