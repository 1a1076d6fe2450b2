#pragma once
// Figures with gnuplot (Debian's gnuplot-nox): a generated script with the
// data inline, rendered by the gnuplot executable to PNG (pngcairo). The
// script is kept beside the image so a reader can restyle and re-render it.
#include <filesystem>
#include <functional>
#include <string>

#include "tagsfm/analysis/experiment_result.h"
#include "tagsfm/core/result.h"

namespace tagsfm::analysis {

// kCairo: anti-aliased PNG (pngcairo), ~150 KB a figure; kCompact: gnuplot's
// libgd PNG terminal, palette colours, ~5x smaller (for committing to docs/).
enum class PlotFormat { kCairo, kCompact };

// The gnuplot script that draws `result` into `image_path` (one panel per
// Panel, one line per series, like the paper's figures).
std::string GnuplotScript(const ExperimentResult& result, const std::filesystem::path& image_path,
                          PlotFormat format = PlotFormat::kCairo);

enum class PlotOutcome { kWritten, kGnuplotMissing };

// Writes `<image_path without extension>.gp` and runs gnuplot on it. An error
// when gnuplot runs but fails (its messages are in `<stem>.gnuplot.log`).
Result<PlotOutcome> RenderPlot(const ExperimentResult& result, const std::filesystem::path& image_path,
                               PlotFormat format = PlotFormat::kCairo);

// The same for any script: `script_for(output)` draws into `output`.
Result<PlotOutcome> RenderGnuplot(const std::function<std::string(const std::filesystem::path&)>& script_for,
                                  const std::filesystem::path& image_path);

}  // namespace tagsfm::analysis
