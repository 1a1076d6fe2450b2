// The sweeps beyond the paper: the project's pose estimator and the error
// model on tag corners, and the whole target pipeline (Slow: ~5-10 s each in
// Release; the estimator runs RANSAC and bundle adjustment).
#include <cstdio>

#include <gtest/gtest.h>

#include "tagsfm/analysis/experiments.h"

namespace tagsfm::analysis {
namespace {

double Value(const ExperimentResult& result, const std::string& noise, const std::string& solver, double tags,
             const std::string& metric, double Summary::*statistic) {
  for (const ConditionRow& row : result.rows) {
    if (row.facet == noise && row.series == solver && row.x == tags && row.metric == metric) return row.stats.*statistic;
  }
  ADD_FAILURE() << "no row " << noise << " " << solver << " " << tags << " " << metric;
  return 0;
}

TEST(AnalysisPipelineSlow, EstimatorsReachTheErrorModelsBoundWithEnoughTags) {
  ExperimentOptions options;
  options.trials = 100;
  options.seed = 11;
  const Result<ExperimentResult> result = RunExperiment("pipeline", options);
  ASSERT_TRUE(result.has_value()) << result.error().message;
  for (const char* noise : {"0.25", "1"}) {
    for (double tags : {10.0, 20.0, 50.0}) {
      for (const char* metric : {"rotation_error_deg", "positional_error_units"}) {
        const double model = Value(*result, noise, "model", tags, metric, &Summary::rms);
        // Maximum likelihood reaches the Cramer-Rao bound at these noise levels;
        // RMS over 100 cameras scatters by ~7%: the 20% bar.
        for (const char* solver : {"EPnP+LM", "tagsfm"}) {
          EXPECT_NEAR(Value(*result, noise, solver, tags, metric, &Summary::rms), model, 0.2 * model)
              << solver << " sigma " << noise << " tags " << tags << " " << metric;
        }
        // EPnP alone is consistent but not optimal: above the bound, by less than 2x.
        const double epnp = Value(*result, noise, "EPnP", tags, metric, &Summary::rms);
        EXPECT_GT(epnp, 0.95 * model);
        EXPECT_LT(epnp, 2.0 * model);
      }
      EXPECT_EQ(Value(*result, noise, "tagsfm", tags, "failure_rate", &Summary::mean), 0.0);
    }
  }
  // Two tags (8 corners, often on one face): a share of EPnP's poses are wild
  // (RMS 36x the bound in the full run), while the project's estimator (with
  // its planar fall-backs) stays near the bound.
  EXPECT_GT(Value(*result, "0.25", "EPnP", 2, "rotation_error_deg", &Summary::rms),
            5.0 * Value(*result, "0.25", "model", 2, "rotation_error_deg", &Summary::rms));
  EXPECT_LT(Value(*result, "0.25", "tagsfm", 2, "rotation_error_deg", &Summary::rms),
            1.5 * Value(*result, "0.25", "model", 2, "rotation_error_deg", &Summary::rms));
}

// The whole target pipeline (no known map) on walk-arounds of the armoire-like box.
TEST(AnalysisPipelineSlow, MapErrorGrowsWithNoiseAndDistance) {
  ExperimentOptions options;
  options.trials = 5;
  options.seed = 5;
  const Result<ExperimentResult> result = RunExperiment("pipeline-map", options);
  ASSERT_TRUE(result.has_value()) << result.error().message;
  auto median = [&](const char* noise, double distance, const char* metric) {
    const ConditionRow* row = result->Find("armoire-box", noise, distance, metric);
    EXPECT_NE(row, nullptr) << noise << " " << distance << " " << metric;
    return row ? row->stats.median : 0.0;
  };
  // 10x the corner noise: the map error grows (7x in the full run; 3x leaves
  // room for 5 walk-arounds and for failures at 1 px).
  EXPECT_GT(median("1", 1.75, "target_corner_rms_mm"), 3 * median("0.1", 1.75, "target_corner_rms_mm"));
  // Twice the distance: camera centres at least 2x worse (4x in the full run:
  // distance x angular error, and fewer pixels per tag).
  EXPECT_GT(median("0.1", 3.5, "camera_centre_median_mm"), 2 * median("0.1", 1.75, "camera_centre_median_mm"));
  // Sub-millimetre map at 0.1 px and 1.75 m (0.2 mm in the full run).
  EXPECT_LT(median("0.1", 1.75, "target_corner_rms_mm"), 1.0);
}

// The hybrid sweep's measurement on three of its walks (~15 s each): the
// feature points' error follows the image noise and the distance, and the
// error model's sigma covers it (the full run's figures in docs/features.md).
TEST(AnalysisPipelineSlow, HybridPointErrorFollowsNoiseAndDistanceWithinItsSigma) {
  auto walk = [](double noise, double distance) {
    synth::SynthOptions render;
    render.frames = 10;
    render.max_azimuth_deg = 30.0;
    render.min_distance = 0.85 * distance;
    render.max_distance = 1.15 * distance;
    render.noise = noise;
    render.seed = 3;
    const Result<HybridWalkFigures> figures = MeasureHybridWalk(render);
    EXPECT_TRUE(figures.has_value()) << figures.error().message;
    std::printf("noise %.0f, %.1f m: %d points, median error %.3f mm, median sigma %.3f mm, %.3f within 2 sigma\n",
                noise, distance, figures ? figures->points : 0, figures ? 1000 * figures->error_median_m : 0,
                figures ? 1000 * figures->sigma_median_m : 0, figures ? figures->within_two_sigma : 0);
    return figures.has_value() ? *figures : HybridWalkFigures{};
  };
  const HybridWalkFigures quiet = walk(1, 2.0), noisy = walk(8, 2.0), far = walk(1, 3.0);
  for (const HybridWalkFigures* f : {&quiet, &noisy, &far}) {
    ASSERT_GT(f->points, 1000);
    // The sigma is honest or conservative (a Gaussian's share within 2 sigma
    // is 0.954; measured 0.955-0.994: 0.955 at noise 8, whose fits' limit
    // follows the lines' error, with the points' noise floored at that limit;
    // without the floor 0.936)...
    EXPECT_GE(f->within_two_sigma, 0.95);
    // ...but not by more than 10x (honest: median error 0.67 sigma; measured
    // 0.14-0.4 sigma).
    EXPECT_GT(f->error_median_m, 0.067 * f->sigma_median_m);
  }
  // 8x the image noise: the points' error at least 2x (3.9x measured at 2 m).
  EXPECT_GT(noisy.error_median_m, 2.0 * quiet.error_median_m);
  // 1.5x the distance: worse (1.25x measured at noise 1; depth x angular error,
  // partly offset by the larger share of the box's near faces in view).
  EXPECT_GT(far.error_median_m, 1.05 * quiet.error_median_m);
  // Sub-millimetre at noise 1 and 2 m (0.19 mm measured).
  EXPECT_LT(quiet.error_median_m, 1e-3);
}

}  // namespace
}  // namespace tagsfm::analysis
