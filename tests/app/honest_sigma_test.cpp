// The sigma that `measure` and `evaluate` give a length between two targets,
// checked against the truth over many lengths (issue 14's "honest sigma"):
// rendered walks, self-surveyed by `tagsfm replay` as a user runs it, every
// tag pair's error E over its sigma pooled. A sigma that describes the
// error gives E / sigma a mean near 0 and a standard deviation near 1.
#include <cmath>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "run_command.h"
#include "test_paths.h"

namespace tagsfm {
namespace {

namespace fs = std::filesystem;
using testing::ReadText;
using testing::RunCommand;
using testing::TagsfmExe;
using testing::TempDir;

// One walk's pairs' E / sigma: rendered, replayed without features, scored.
std::vector<double> ErrorOverSigma(const fs::path& dir, int seed, const std::string& lens) {
  const std::string exe = TagsfmExe().string();
  const fs::path rec = dir / "rec", out = dir / "out", config = dir / "config.yaml";
  EXPECT_EQ(RunCommand(exe + " synth box --out " + rec.string() +
                           " --frames 20 --width 1280 --height 720 --noise 2 --blur 0.7 --threads 2 --seed " +
                           std::to_string(seed) + lens,
                       dir / "synth.log"),
            0)
      << ReadText(dir / "synth.log");
  // The renderer prints every tag exactly at its nominal size: the print
  // tolerance a length's sigma must carry is then 0, and what remains is the
  // adjustment's covariance.
  std::ofstream(config) << "pipeline:\n  recon:\n    tag_size_sigma_rel: 0\n";
  EXPECT_EQ(RunCommand(exe + " replay " + rec.string() + " --out " + out.string() + " --no-features --config " +
                           config.string(),
                       dir / "replay.log"),
            0)
      << ReadText(dir / "replay.log");
  EXPECT_EQ(RunCommand(exe + " evaluate " + out.string() + " " + rec.string() + " 2> " + (dir / "eval.err").string(),
                       dir / "eval.json"),
            0)
      << ReadText(dir / "eval.err");
  std::vector<double> ratios;
  const nlohmann::json e = nlohmann::json::parse(ReadText(dir / "eval.json"), nullptr, false);
  if (e.is_discarded() || !e.contains("lengths") || e["lengths"].is_null()) {
    ADD_FAILURE() << "seed " << seed << ": no lengths in evaluate's output";
    return ratios;
  }
  for (const auto& pair : e["lengths"]["pairs"]) {
    if (pair["sigma_m"].is_number() && pair["sigma_m"].get<double>() > 0) {
      ratios.push_back(pair["error_m"].get<double>() / pair["sigma_m"].get<double>());
    }
  }
  return ratios;
}

// Eight 20-frame 1280x720 box walks (noise 2, blur 0.7), seeds 1-8, a lens
// with k1 -0.05 on the even ones, tags printed with one module of white
// (the default) on six walks and two on seeds 7 and 8. Pooled, not per
// walk: a walk's pairs share their tags and its scale, so one walk's E /
// sigma spread is that of a few numbers (per walk the mean ran -1.2 to
// +0.6 and the std 0.3-0.9). Measured 2026-12-06: 2,535 pairs, mean -0.28,
// std 0.79, none beyond 3 sigma (all eight at one module: -0.24, 0.79);
// with the default 200 ppm print term in every sigma the std is 0.35
// (conservative by design, since these prints are exact). Bounds: the
// issue's (mean within +-0.5, std 0.7-1.5).
TEST(HonestSigmaSlow, LengthErrorsOverTheirSigmaPooledOverWalks) {
  std::vector<double> pooled;
  for (int seed = 1; seed <= 8; ++seed) {
    TempDir scratch;
    std::string options = seed % 2 == 0 ? " --distortion -0.05,0.01,0,0" : "";
    if (seed >= 7) options += " --tag-margin 2";
    const std::vector<double> ratios = ErrorOverSigma(scratch.path(), seed, options);
    EXPECT_GT(ratios.size(), 100u) << "seed " << seed;  // 23-28 tags mapped: 250-380 pairs
    pooled.insert(pooled.end(), ratios.begin(), ratios.end());
  }
  ASSERT_GT(pooled.size(), 1000u);
  double sum = 0, sum_sq = 0;
  int beyond = 0;
  for (double r : pooled) {
    sum += r;
    beyond += std::abs(r) > 3;
  }
  const double mean = sum / static_cast<double>(pooled.size());
  for (double r : pooled) sum_sq += (r - mean) * (r - mean);
  const double std_dev = std::sqrt(sum_sq / static_cast<double>(pooled.size() - 1));
  std::printf("E / sigma over %zu pairs of 8 walks: mean %.3f, std %.3f, beyond 3 sigma %d\n", pooled.size(), mean,
              std_dev, beyond);
  EXPECT_LT(std::abs(mean), 0.5);
  EXPECT_GT(std_dev, 0.7);
  EXPECT_LT(std_dev, 1.5);
  EXPECT_LT(beyond, static_cast<int>(0.01 * static_cast<double>(pooled.size())));
}

}  // namespace
}  // namespace tagsfm
