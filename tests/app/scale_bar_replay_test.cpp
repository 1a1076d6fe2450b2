// One scale bar through `tagsfm replay` as a user runs it (feature points
// included), on rendered walks whose tags are printed 0.5 % too large
// (issue 14: the scale within 50 ppm of the truth). The bare reconstructor's
// case, without the points, is tests/recon/scale_bars_test.cpp.
#include <cmath>
#include <fstream>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "evaluate_command.h"
#include "json_file.h"
#include "rendered_walk.h"
#include "run_command.h"
#include "tagsfm/core/csv_formats.h"
#include "tagsfm/recon/tag_geometry.h"
#include "test_paths.h"

namespace tagsfm {
namespace {

namespace fs = std::filesystem;
using testing::EvaluateAgainstTruth;
using testing::ReadJsonFile;
using testing::ReadText;
using testing::RunCommand;
using testing::SynthWalkCommand;
using testing::TagsfmExe;
using testing::TempDir;

// Renders the walk, then puts a bar where a surveyor would: between the two
// tags with five views or more in a first survey's adjustment (report.json's
// targets) that lie farthest apart, at its true length (certificate sigma
// 10 um).
fs::path RenderWithBar(const fs::path& dir, int seed, const std::string& lens) {
  const std::string exe = TagsfmExe().string();
  const fs::path rec = dir / "rec";
  EXPECT_EQ(RunCommand(SynthWalkCommand(rec, seed, " --print-scale 1.005" + lens), dir / "synth.log"), 0)
      << ReadText(dir / "synth.log");
  EXPECT_EQ(RunCommand(exe + " replay " + rec.string() + " --out " + (dir / "first").string() + " --no-features",
                       dir / "first.log"),
            0)
      << ReadText(dir / "first.log");
  std::vector<int> well_seen;
  const nlohmann::json first = ReadJsonFile(dir / "first/report.json");
  if (first.is_object()) {
    for (const auto& t : first["targets"]) {
      if (t["views"].get<int>() >= 5) well_seen.push_back(t["tag"].get<int>());
    }
  }
  const auto truth = ReadTargetsCsv(rec / "ground_truth/targets.csv");
  EXPECT_TRUE(truth.has_value());
  std::pair<int, int> bar{-1, -1};
  double length = 0;
  for (const int a : well_seen) {
    for (const int b : well_seen) {
      if (!truth || !truth->count(a) || !truth->count(b)) continue;
      const double l = (TagCenter(truth->at(a)) - TagCenter(truth->at(b))).norm();
      if (l > length) {
        length = l;
        bar = {a, b};
      }
    }
  }
  EXPECT_GT(length, 1.0);
  // The synth writes the targets block last: the bar goes under it.
  std::ofstream(rec / "recording.yaml", std::ios::app)
      << "  scale_bars:\n    - {a: " << bar.first << ", b: " << bar.second << ", length_m: " << std::to_string(length)
      << ", sigma_m: 0.00001}\n";
  return rec;
}

// Seeds and lens varied, none tuned (the same two walks as ScaleBarsSlow).
// Measured 2026-12-06, scale by the lengths weighted by their sigma: seed 3
// (bar 1-9, 1.417 m) -17.7 ppm, seed 8 (k1 -0.05, bar 3-27, 1.284 m) +0.1
// ppm, at a reported sigma of 52 and 57 ppm. With the bars picked by the
// frames that detect reads (9-24 and 3-24; tag 24 has fewer than five views
// in the adjustment) -2.7 and -7.9 ppm at 50 and 52 ppm. Bounds: the
// issue's 50 ppm, and the reported sigma honest (within 3 of it).
TEST(ScaleBarReplaySlow, OneBarFixesAPrinterHalfAPercentOffWithinFiftyPpm) {
  for (const auto& [seed, lens] : std::vector<std::pair<int, std::string>>{{3, ""}, {8, " --distortion -0.05,0.01,0,0"}}) {
    TempDir scratch;
    const fs::path rec = RenderWithBar(scratch.path(), seed, lens), out = scratch.path() / "out";
    const std::string exe = TagsfmExe().string();
    ASSERT_EQ(RunCommand(exe + " replay " + rec.string() + " --out " + out.string(), scratch.path() / "replay.log"), 0)
        << ReadText(scratch.path() / "replay.log");
    const nlohmann::json report = ReadJsonFile(out / "report.json");
    const nlohmann::json evaluation = EvaluateAgainstTruth(out, rec, scratch.path());
    ASSERT_TRUE(report.is_object() && evaluation.is_object());
    ASSERT_EQ(report["scale"]["source"], "scale bars") << report["scale"].dump();
    EXPECT_NEAR(report["scale"]["factor"].get<double>(), 1.005, 1e-3);
    const double scale_error_ppm = evaluation["lengths"]["weighted_error_per_length_ppm"].get<double>();
    const double sigma_ppm = 1e6 * report["scale"]["sigma_rel"].get<double>();
    const nlohmann::json& bar = report["scale"]["scale_bars"][0];
    std::printf("seed %d: bar %s-%s %.3f m; scale error %+.1f ppm (lengths weighted by sigma), reported sigma %.1f ppm, "
                "factor %.6f\n",
                seed, bar["a"].dump().c_str(), bar["b"].dump().c_str(), bar["certified_m"].get<double>(),
                scale_error_ppm, sigma_ppm, report["scale"]["factor"].get<double>());
    EXPECT_LT(std::abs(scale_error_ppm), 50.0) << "seed " << seed;
    EXPECT_LT(std::abs(scale_error_ppm), 3 * sigma_ppm) << "seed " << seed;
  }
}

}  // namespace
}  // namespace tagsfm
