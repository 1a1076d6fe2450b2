// Corner accuracy against exactly known corners: tags rendered under known
// homographies (area-averaged, blurred, noised; see synthetic_tags.h).
#include <cmath>
#include <cstdio>
#include <map>
#include <string>

#include <gtest/gtest.h>

#include "corner_stats.h"
#include "tagsfm/detect/synthetic_tags.h"
#include "tagsfm/detect/tag_detector.h"

namespace tagsfm {
namespace {

using testing::CornerStats;

struct SceneSpec {
  int width = 1280;
  int height = 720;
  int tags = 40;
  double side_px = 24.0;  // 3 px per module for tag36h11's 8 modules
  double tilt_deg = 50.0;
  double blur = 0.7;
  double noise = 2.0;
  int frames = 3;
};

struct Scene {
  std::vector<PlacedTag> truth;
  cv::Mat image;
};

// Rendering at exact coverage is the slow part: each spec is rendered once.
const std::vector<Scene>& Scenes(const SceneSpec& spec) {
  static std::map<std::string, std::vector<Scene>> cache;
  const std::string key = std::to_string(spec.side_px) + "/" + std::to_string(spec.blur) + "/" +
                          std::to_string(spec.noise) + "/" + std::to_string(spec.tilt_deg);
  auto it = cache.find(key);
  if (it != cache.end()) return it->second;
  std::vector<Scene> scenes;
  for (int f = 0; f < spec.frames; ++f) {
    Scene scene;
    scene.truth = RandomTagPlacements(spec.width, spec.height, spec.tags, spec.side_px, spec.tilt_deg, 100 + f);
    TagRenderOptions render;
    render.blur_sigma_px = spec.blur;
    render.noise_sigma = spec.noise;
    render.seed = 7 + f;
    auto image = RenderTags("tag36h11", spec.width, spec.height, scene.truth, render);
    EXPECT_TRUE(image.has_value());
    if (image) scene.image = *image;
    scenes.push_back(std::move(scene));
  }
  return cache.emplace(key, std::move(scenes)).first->second;
}

CornerStats Measure(const SceneSpec& spec, TagDetectorOptions options) {
  auto detector = TagDetector::Create(options);
  EXPECT_TRUE(detector.has_value()) << detector.error().message;
  CornerStats stats;
  int frame = 0;
  for (const Scene& scene : Scenes(spec)) {
    auto detections = (*detector)->Detect(scene.image, frame++);
    EXPECT_TRUE(detections.has_value());
    testing::AccumulateCornerStats(scene.truth, *detections, &stats);
  }
  return stats;
}

TagDetectorOptions WithRefinement(CornerRefinement refinement, float decimate = 2.0f) {
  TagDetectorOptions options;
  options.refinement = refinement;
  options.quad_decimate = decimate;
  return options;
}

// The condition: 1280x720, tag sides ~24 px (3 px per module), noise
// 2 grey levels, blur 0.7 px, tilts up to 50 degrees; 3 frames x 40 tags.
// Prints every method's figures (docs/detection.md quotes them).
TEST(CornerAccuracySlow, ComparesMethodsOnSmallTags) {
  const SceneSpec spec;
  std::map<std::string, CornerStats> results;
  for (CornerRefinement r : {CornerRefinement::kNone, CornerRefinement::kAprilTag, CornerRefinement::kCornerSubPix,
                             CornerRefinement::kEdgeLineFit}) {
    for (float decimate : {1.0f, 2.0f}) {
      TagDetectorOptions options = WithRefinement(r, decimate);
      options.refine_edges = r != CornerRefinement::kNone;
      const CornerStats stats = Measure(spec, options);
      std::printf("%-13s decimate %.0f: %s\n", CornerRefinementName(r), decimate, stats.Summary().c_str());
      results[std::string(CornerRefinementName(r)) + std::to_string(static_cast<int>(decimate))] = stats;
    }
  }
  // The chosen default (edge line fit) against the targets: median
  // <= 0.05 px, p95 <= 0.2 px, on every tag found at full resolution.
  // Measured (docs/detection.md): median 0.0119, p95 0.029, max 0.075, bias
  // -0.0005 px (one module of white; two: 0.0115, 0.027, 0.068, -0.0002); the bounds below leave room for code changes that move the
  // figures by their sampling error (the bias's is ~0.0007 px over 480
  // corners with ~0.015 px scatter), not for a return of the +0.01 px bias.
  const CornerStats& fit = results["edgelinefit1"];
  EXPECT_EQ(fit.found_tags, fit.truth_tags);
  EXPECT_EQ(fit.wrong_ids, 0);
  EXPECT_LE(fit.Median(), 0.02);
  EXPECT_LE(fit.Percentile(0.95), 0.05);
  EXPECT_LE(fit.Max(), 0.15);
  EXPECT_LE(std::abs(fit.bias), 0.002);
  // And it must beat libapriltag's own refinement, the thing it replaces.
  const CornerStats& plain = results["apriltag1"];
  EXPECT_LT(fit.Median(), 0.5 * plain.Median());
  EXPECT_LT(fit.Percentile(0.95), 0.5 * plain.Percentile(0.95));
  EXPECT_LT(std::abs(fit.bias), std::abs(plain.bias));
  // At quad_decimate 2 libapriltag may miss some of these small tilted tags
  // (docs/detection.md), but what it finds must be as accurate. With one
  // module of white (the default since the margin option) libapriltag's
  // corners of one tag are 3.6 px off (with refine_edges; every method
  // keeps them: the edge fit declines a start that far off), which alone
  // moves the plain mean to -0.006 px: the bias is over the corners within
  // 0.5 px (-0.0008), and that tag is the only one beyond.
  const CornerStats& fit2 = results["edgelinefit2"];
  EXPECT_GE(fit2.found_tags, fit2.truth_tags * 8 / 10);
  EXPECT_EQ(fit2.wrong_ids, 0);
  EXPECT_LE(fit2.Median(), 0.02);
  EXPECT_LE(std::abs(fit2.InlierBias()), 0.002);
  EXPECT_LE(fit2.CountAbove(0.5), 4);
}

// The scene at quad_decimate 2, where libapriltag loses 12-15 of the
// 120 tilted tags: the small-tag pass finds them all (measured 120/120, max
// corner error 0.072 px at two modules of white; at one, 4 corners of the
// tag libapriltag places 3.6 px off), at ~1.6x the CPU of the detection
// without it (82 vs 50 ms per frame) and still under half of quad_decimate 1's.
TEST(CornerAccuracySlow, SmallTagPassRecoversTheTiltedTagsAtDecimate2) {
  const SceneSpec spec;
  TagDetectorOptions options = WithRefinement(CornerRefinement::kEdgeLineFit, 2.0f);
  const CornerStats without = Measure(spec, options);
  options.small_tag_pass = true;
  const CornerStats with = Measure(spec, options);
  std::printf("decimate 2 without the pass: %s\n             with: %s\n", without.Summary().c_str(),
              with.Summary().c_str());
  EXPECT_LT(without.found_tags, without.truth_tags);
  EXPECT_EQ(with.found_tags, with.truth_tags);
  EXPECT_EQ(with.wrong_ids, 0);
  EXPECT_LE(with.Median(), 0.02);
  // Every corner within 0.15 px but those of the one tag whose libapriltag
  // corners are 3.6 px off at one module of white (see above).
  EXPECT_LE(with.CountAbove(0.15), 4);
  EXPECT_LE(std::abs(with.InlierBias()), 0.003);
}

// Strongly tilted small tags (3 px modules, tilts up to 70 degrees: down to
// ~1 px per module across the foreshortened direction), noise-free so that
// only model error is left. The first edge model's bias grew with tilt to
// +0.046 px here (the border's depth taken along the slanted "inward"
// direction, docs/detection.md); measured now (2 frames, the 72 of 80 tags
// libapriltag finds at such tilts) bias ~0.000 px, median ~0.005, p95
// ~0.03 px. Bias bound: 0.003 px, the target (~4x the bias's
// sampling error over ~280 corners).
TEST(CornerAccuracy, EdgeFitIsUnbiasedOnStronglyTiltedTags) {
  SceneSpec spec;
  spec.tilt_deg = 70.0;
  spec.noise = 0.0;
  spec.frames = 2;
  const CornerStats stats = Measure(spec, WithRefinement(CornerRefinement::kEdgeLineFit, 1.0f));
  std::printf("edgelinefit tilt <= 70, noise 0: %s\n", stats.Summary().c_str());
  // Recall at 70 degrees is libapriltag's quad detection, not this test's subject.
  ASSERT_GE(stats.found_tags, stats.truth_tags * 3 / 4);
  EXPECT_EQ(stats.wrong_ids, 0);
  EXPECT_LE(std::abs(stats.bias), 0.003);
  EXPECT_LE(stats.Median(), 0.02);
  EXPECT_LE(stats.Percentile(0.95), 0.1);
}

// Large, noise-free, frontal tags: the edge fit must be near-exact there
// (the test of the model itself, and of the renderer's convention agreeing
// with it). Strongly tilted large tags are less exact (docs/detection.md).
TEST(CornerAccuracy, EdgeFitIsExactOnCleanLargeTags) {
  SceneSpec spec;
  spec.side_px = 64.0;
  spec.noise = 0.0;
  spec.tilt_deg = 0.0;
  spec.tags = 12;
  spec.frames = 1;
  const CornerStats stats = Measure(spec, WithRefinement(CornerRefinement::kEdgeLineFit, 1.0f));
  std::printf("edgelinefit clean 64 px: %s\n", stats.Summary().c_str());
  ASSERT_EQ(stats.found_tags, stats.truth_tags);
  // Measured: median 0.0023, p95 0.0065, bias 0.0000 px.
  EXPECT_LE(stats.Percentile(0.95), 0.015);
  EXPECT_LE(std::abs(stats.bias), 0.001);
}

// Pins the pixel convention: libapriltag's raw corners, shifted by half a
// pixel, must centre on the exact corners. Unshifted they would be off by
// (+0.5, +0.5); the reported extra 0.125 px would show as a mean offset of
// that size.
TEST(CornerAccuracy, RawCornersFollowOpenCvPixelConvention) {
  // libapriltag's refine_edges on: without it its corners sit a further
  // ~0.045 px (decimate 1) to ~0.09 px (decimate 2) towards -x and -y
  // (measured here; cf. upstream issue #334), which kNone leaves as it is.
// One frame: 160 corners with ~0.1 px scatter give the mean to ~0.01 px.
  TagDetectorOptions options = WithRefinement(CornerRefinement::kNone, 1.0f);
  options.refine_edges = true;
  SceneSpec spec;
  spec.frames = 1;
  const CornerStats stats = Measure(spec, options);
  ASSERT_EQ(stats.found_tags, stats.truth_tags);
  EXPECT_EQ(stats.wrong_ids, 0);
  EXPECT_NEAR(stats.mean_x, 0.0, 0.02);
  EXPECT_NEAR(stats.mean_y, 0.0, 0.02);
  EXPECT_LT(stats.Median(), 0.15);
}

}  // namespace
}  // namespace tagsfm
