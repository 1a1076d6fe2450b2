// The gnuplot script and the rendered figure.
#include <fstream>
#include <string>

#include <gtest/gtest.h>

#include "tagsfm/analysis/plot.h"
#include "test_paths.h"

namespace tagsfm::analysis {
namespace {

ExperimentResult TwoSeriesResult() {
  ExperimentResult result;
  result.name = "demo";
  result.title = "Demo \"quoted\" title";
  result.series_column = "noise_px";
  result.series_legend = "σ = %s px";
  result.x_column = "depth";
  result.x_label = "camera depth (units)";
  for (const char* series : {"0", "2"}) {
    for (double x : {2.0, 4.0, 6.0}) {
      Summary stats;
      stats.mean = std::string(series) == "0" ? 0.0 : 0.01 * x;
      stats.median = stats.mean;
      stats.count = 10;
      result.rows.push_back({"box", "", series, x, "positional_error_units", stats});
    }
  }
  result.panels = {{"box", "", "positional_error_units", Statistic::kMean, "positional error (units)", true}};
  return result;
}

TEST(AnalysisPlot, ScriptHasLabelsLegendAndInlineData) {
  const std::string script = GnuplotScript(TwoSeriesResult(), "/tmp/out dir/demo.png");
  EXPECT_NE(script.find("set output \"/tmp/out dir/demo.png\""), std::string::npos);
  EXPECT_NE(script.find("Demo \\\"quoted\\\" title"), std::string::npos);
  EXPECT_NE(script.find("set xlabel \"camera depth (units)\""), std::string::npos);
  EXPECT_NE(script.find("set ylabel \"positional error (units)\""), std::string::npos);
  EXPECT_NE(script.find("title \"σ = 2 px\""), std::string::npos);
  EXPECT_NE(script.find("4 0.04\n"), std::string::npos);
  // A log axis cannot show the all-zero series: it is left out, not plotted as garbage.
  EXPECT_EQ(script.find("title \"σ = 0 px\""), std::string::npos);
}

TEST(AnalysisPlot, RendersAPngWhenGnuplotIsInstalled) {
  testing::TempDir dir;
  const std::filesystem::path image = dir.path() / "demo.png";
  const Result<PlotOutcome> outcome = RenderPlot(TwoSeriesResult(), image);
  ASSERT_TRUE(outcome.has_value()) << outcome.error().message;
  if (*outcome == PlotOutcome::kGnuplotMissing) GTEST_SKIP() << "gnuplot is not installed";
  std::ifstream file(image, std::ios::binary);
  char signature[8] = {};
  file.read(signature, 8);
  EXPECT_EQ(std::string(signature + 1, 3), "PNG");
  EXPECT_GT(std::filesystem::file_size(image), 2000u);
  EXPECT_TRUE(std::filesystem::exists(dir.path() / "demo.gp"));
  EXPECT_FALSE(std::filesystem::exists(dir.path() / "demo.png.tmp"));
  EXPECT_FALSE(std::filesystem::exists(dir.path() / "demo.gnuplot.log"));
}

TEST(AnalysisPlot, CompactFormatUsesThePaletteTerminal) {
  EXPECT_NE(GnuplotScript(TwoSeriesResult(), "x.png", PlotFormat::kCompact).find("set terminal png noenhanced"),
            std::string::npos);
  testing::TempDir dir;
  const Result<PlotOutcome> outcome = RenderPlot(TwoSeriesResult(), dir.path() / "demo.png", PlotFormat::kCompact);
  ASSERT_TRUE(outcome.has_value()) << outcome.error().message;
  if (*outcome == PlotOutcome::kGnuplotMissing) GTEST_SKIP() << "gnuplot is not installed";
  EXPECT_GT(std::filesystem::file_size(dir.path() / "demo.png"), 1000u);
}

}  // namespace
}  // namespace tagsfm::analysis
