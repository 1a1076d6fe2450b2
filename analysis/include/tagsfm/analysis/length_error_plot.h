#pragma once
// The length-measurement error against the length, as VDI/VDE 2634-1 draws
// it: one point per tag pair (error in mm against the true length in m),
// with the pairs' ±2 sigma as a band when the result has a covariance.
#include <filesystem>
#include <string>

#include "tagsfm/analysis/plot.h"
#include "tagsfm/eval/evaluation.h"

namespace tagsfm::analysis {

std::string LengthErrorScript(const eval::LengthErrors& lengths, const std::string& title,
                              const std::filesystem::path& image_path);

Result<PlotOutcome> RenderLengthErrorPlot(const eval::LengthErrors& lengths, const std::string& title,
                                          const std::filesystem::path& image_path);

}  // namespace tagsfm::analysis
