// A self-survey that closes a loop (issue 14: "loop closure when many old
// tags disagree at once"): `tagsfm synth room` walks round the inside of a
// room with targets on its four walls and turns 400 degrees, so the walls it
// began with come back at the end, seen from poses that drifted on the way.
// Through `tagsfm replay` as a user runs it (tracking tag search), against
// the truth.
#include <cmath>
#include <cstdio>
#include <fstream>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "evaluate_command.h"
#include "json_file.h"
#include "run_command.h"
#include "test_paths.h"

namespace tagsfm {
namespace {

namespace fs = std::filesystem;
using testing::EvaluateAgainstTruth;
using testing::LengthErrorsOverSigma;
using testing::Pool;
using testing::PooledRatios;
using testing::ReadJsonFile;
using testing::ReadText;
using testing::RunCommand;
using testing::TagsfmExe;
using testing::TempDir;

// Two rooms, lens and print margin varied, none tuned. Measured 2026-12-06
// (1280x720, 120 frames, 100 degrees a second: a fast turn):
// - seed 5: 120 of 120 frames, 27 of 27 tags mapped, 1:7,978 after a rigid
//   fit, -95 ppm. Before the entry bands held two frames of inflow, 50 of
//   120 frames (a tag nearer than the rest, twice their size, came in
//   beside the bands and was missed for 7 frames, and the chain of views
//   broke); before the waiting tags were tried again after the first
//   adjustment, tags 12 and 19 were left out (their views on both sides of
//   the loop fitted at 4.6 and 2.7 px before it); before full-frame passes
//   followed the motion, tag 14 too (read in too few frames).
// - seed 9, k1 -0.05, tag margin 2: 120 of 120, 30 of 30 mapped, 1:12,449,
//   +105 ppm.
// - E/sigma pooled over both rooms' 786 tag pairs: mean -0.19, std 1.02
//   (each room alone is offset by its own scale error, e.g. +0.53 and
//   -0.68 before the motion rule).
// - The scale's sigma (report.json's scale.total_sigma_rel) 65 and 48 ppm:
//   the errors are 1.5 and 2.2 of it.
// Bounds: every frame registered; every tag left out only for too narrow a
// span of views or a single view; the map within 1:5,000 of the room's size
// (the 1:10,000 is for walks round an object: here 6 cm tags 2-2.5 m
// away are seen from a camera that mostly turns on the spot); the scale
// within 200 ppm and within 3 of its own sigma; pooled E/sigma as the issue asks (mean within +-0.5,
// standard deviation 0.7-1.5).
TEST(RoomLoopSlow, AWalkRoundARoomClosesItsLoopWithEveryTagItCanMap) {
  const std::vector<std::pair<int, std::string>> rooms = {{5, ""}, {9, " --distortion=-0.05,0.01,0,0 --tag-margin 2"}};
  std::vector<double> pooled;
  for (const auto& [seed, options] : rooms) {
    TempDir scratch;
    const fs::path rec = scratch.path() / "rec", out = scratch.path() / "out", config = scratch.path() / "config.yaml";
    const std::string exe = TagsfmExe().string();
    ASSERT_EQ(RunCommand(exe + " synth room --out " + rec.string() + " --frames 120 --threads 2 --seed " +
                             std::to_string(seed) + options,
                         scratch.path() / "synth.log"),
              0)
        << ReadText(scratch.path() / "synth.log");
    // Tags printed exactly at their nominal size: no print tolerance in sigma.
    std::ofstream(config) << "pipeline:\n  recon:\n    tag_size_sigma_rel: 0\n";
    ASSERT_EQ(RunCommand(exe + " replay " + rec.string() + " --out " + out.string() + " --no-features --config " +
                             config.string(),
                         scratch.path() / "replay.log"),
              0)
        << ReadText(scratch.path() / "replay.log");
    const nlohmann::json report = ReadJsonFile(out / "report.json");
    const nlohmann::json evaluation = EvaluateAgainstTruth(out, rec, scratch.path());
    ASSERT_TRUE(report.is_object() && evaluation.is_object());
    const nlohmann::json& map = evaluation["map"];
    const std::vector<double> ratios = LengthErrorsOverSigma(evaluation);
    pooled.insert(pooled.end(), ratios.begin(), ratios.end());
    std::printf("room seed %d: %d of %d frames, %d of %d tags mapped, 1:%.0f rigid, %+.0f ppm\n", seed,
                report["registered_frames"].get<int>(), report["frames"].get<int>(),
                report["targets_mapped"].get<int>(), report["targets_seen"].get<int>(),
                map["rigid_ratio"].get<double>(), map["scale_error_ppm"].get<double>());
    EXPECT_EQ(report["registered_frames"].get<int>(), report["frames"].get<int>()) << "seed " << seed;
    for (const nlohmann::json& left_out : report["unmapped_targets"]) {
      const std::string why = left_out["reason"].get<std::string>();
      const bool unavoidable = why.find("deg (at least") != std::string::npos || why.find("one") != std::string::npos;
      EXPECT_TRUE(unavoidable) << "seed " << seed << ": tag " << left_out["tag"] << " " << why;
    }
    EXPECT_GT(map["rigid_ratio"].get<double>(), 5000) << "seed " << seed;
    EXPECT_LT(std::abs(map["scale_error_ppm"].get<double>()), 200) << "seed " << seed;
    ASSERT_TRUE(report["scale"]["total_sigma_rel"].is_number()) << "seed " << seed;
    const double scale_sigma_ppm = 1e6 * report["scale"]["total_sigma_rel"].get<double>();
    std::printf("room seed %d: scale sigma %.0f ppm\n", seed, scale_sigma_ppm);
    EXPECT_LT(std::abs(map["scale_error_ppm"].get<double>()), 3 * scale_sigma_ppm) << "seed " << seed;
  }
  ASSERT_GT(pooled.size(), 300u);
  const PooledRatios e = Pool(pooled);
  std::printf("E/sigma over %zu pairs: mean %.2f, std %.2f\n", pooled.size(), e.mean, e.std_dev);
  EXPECT_LT(std::abs(e.mean), 0.5);
  EXPECT_GT(e.std_dev, 0.7);
  EXPECT_LT(e.std_dev, 1.5);
}

}  // namespace
}  // namespace tagsfm
