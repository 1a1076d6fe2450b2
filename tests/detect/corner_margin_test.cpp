// The edge fit on tags printed with the white margins real prints have: 1
// module (libapriltag's official image printed edge to edge), 2 and 3, a
// textured surface right up to the margin, a shade per tag; tilts up to 70
// degrees, blurs 0.5-1.0 px, modules 2.5-5 px, noise 2, with and without a
// distorting lens. Truth is exact (synthetic_tags.h). Measured three ways:
// the fit alone from the true corners moved by ~0.2 px, the detector on the
// full frame (with the lens where there is one, as `tagsfm detect --camera`),
// and the tracker on the next frames (without the lens, as replay tracks).
//
// Before the fit bounded its white side by the one-module ring and gave
// what lies beyond a level of its own (docs/detection.md), margin 1 gave an
// inward bias of -0.021 px (fit), -0.019 (detector), -0.017 (tracking) here.
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>
#include <random>

#include <gtest/gtest.h>

#include "corner_stats.h"
#include "tagsfm/detect/synthetic_tags.h"
#include "tagsfm/detect/tag_detector.h"
#include "tagsfm/detect/tag_layout.h"
#include "tagsfm/detect/tag_tracker.h"

namespace tagsfm {
namespace {

using testing::CornerStats;

CameraModel WideLens() {
  CameraModel camera;
  camera.width = 1280;
  camera.height = 720;
  camera.fx = camera.fy = 700.0;
  camera.cx = 639.5;
  camera.cy = 359.5;
  camera.distortion = {-0.25, 0.08, 0.0005, -0.0003, 0.0};
  return camera;
}

// One frame's conditions: every field varies between the frames, none is
// the same for all (nothing tuned to one scene).
struct FrameSpec {
  double side_px;   // tag side; tag36h11 has 8 modules across
  double tilt_deg;  // maximum tilt
  double blur;
  double texture;   // grey levels either side of the background's mean
  double background;
  bool lens;
};
constexpr std::array<FrameSpec, 4> kFrames = {{
    {20.0, 70.0, 0.6, 100.0, 110.0, false},
    {24.0, 60.0, 0.8, 60.0, 150.0, true},
    {32.0, 70.0, 0.5, 120.0, 90.0, false},
    {40.0, 50.0, 1.0, 80.0, 130.0, true},
}};

struct Frame {
  std::vector<PlacedTag> truth;  // image corners (through the lens where there is one)
  cv::Mat image;
};

// The frame's tags moved by `shift` px (in undistorted coordinates), rendered.
Frame RenderFrame(const FrameSpec& spec, double margin, int index, int step) {
  const int width = 1280, height = 720;
  static const CameraModel lens = WideLens();
  std::vector<PlacedTag> placed = RandomTagPlacements(width, height, 40, spec.side_px, spec.tilt_deg, 300 + index);
  for (PlacedTag& tag : placed) {
    for (Eigen::Vector2d& c : tag.corners) c += Eigen::Vector2d(2.1 * step, 1.3 * step);
  }
  TagRenderOptions render;
  render.blur_sigma_px = spec.blur;
  render.noise_sigma = 2.0;
  render.margin_modules = margin;
  render.texture_contrast = spec.texture;
  render.background = spec.background;
  render.tag_shade_variation = 0.4;
  render.seed = static_cast<std::uint64_t>(1000 * margin + 10 * index + step);
  render.camera = spec.lens ? &lens : nullptr;
  Frame frame;
  const Result<cv::Mat> image = RenderTags("tag36h11", width, height, placed, render);
  EXPECT_TRUE(image.has_value()) << image.error().message;
  if (image) frame.image = *image;
  frame.truth = placed;
  if (spec.lens) {
    for (PlacedTag& tag : frame.truth) {
      for (Eigen::Vector2d& c : tag.corners) {
        c = lens.Project(Eigen::Vector3d((c.x() - lens.cx) / lens.fx, (c.y() - lens.cy) / lens.fy, 1.0));
      }
    }
  }
  return frame;
}

struct MarginStats {
  CornerStats fit;        // RefineCornersByEdgeLines from the truth moved by ~0.2 px
  CornerStats detector;   // TagDetector, full frame
  CornerStats tracking;   // TagTracker, the frames after the first
};

// Frames per condition: the first is detected in full, the next ones tracked.
constexpr int kSteps = 2;

const MarginStats& Measure(double margin) {
  static std::map<double, MarginStats> cache;
  auto it = cache.find(margin);
  if (it != cache.end()) return it->second;
  MarginStats stats;
  const CameraModel lens = WideLens();
  std::mt19937 rng(static_cast<unsigned>(17 * margin));
  double render_s = 0.0;
  for (size_t f = 0; f < kFrames.size(); ++f) {
    const FrameSpec& spec = kFrames[f];
    TagDetectorOptions detector_options;
    if (spec.lens) detector_options.camera = lens;
    auto detector = TagDetector::Create(detector_options);
    auto tracker = TagTracker::Create(TagDetectorOptions{}, TagTrackerOptions{});
    EXPECT_TRUE(detector.has_value() && tracker.has_value());
    if (!detector || !tracker) break;
    for (int step = 0; step < kSteps; ++step) {
      const auto start = std::chrono::steady_clock::now();
      const Frame frame = RenderFrame(spec, margin, static_cast<int>(f), step);
      render_s += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      if (frame.image.empty()) continue;
      auto tracked = (*tracker)->Track(frame.image, step);
      EXPECT_TRUE(tracked.has_value());
      if (step > 0 && tracked) testing::AccumulateCornerStats(frame.truth, *tracked, &stats.tracking);
      if (step != 0) continue;
      auto detected = (*detector)->Detect(frame.image, step);
      EXPECT_TRUE(detected.has_value());
      if (detected) testing::AccumulateCornerStats(frame.truth, *detected, &stats.detector);
      const DetectionSet fitted = testing::FitFromMovedTruth(frame.image, frame.truth, rng, spec.lens ? &lens : nullptr);
      testing::AccumulateCornerStats(frame.truth, fitted, &stats.fit);
    }
  }
  std::printf("margin %.0f (rendering %.1f s)\n  fit:      %s\n  detector: %s\n  tracking: %s\n", margin, render_s,
              stats.fit.Summary().c_str(), stats.detector.Summary().c_str(), stats.tracking.Summary().c_str());
  return cache.emplace(margin, std::move(stats)).first->second;
}

// The targets: bias <= 0.003 px, median <= 0.03, p95 <= 0.12 (the
// bias over the corners within 0.5 px: the detector keeps libapriltag's
// corners, 1.5-2.3 px off, on the one tag per margin where the fit
// declines).
void ExpectTargets(const CornerStats& stats, const char* what, double margin, double max_bias = 0.003) {
  EXPECT_EQ(stats.wrong_ids, 0) << what << " margin " << margin;
  EXPECT_LE(std::abs(stats.InlierBias()), max_bias) << what << " margin " << margin;
  EXPECT_LE(stats.Median(), 0.03) << what << " margin " << margin;
  EXPECT_LE(stats.Percentile(0.95), 0.12) << what << " margin " << margin;
}

void ExpectMarginTargets(double margin) {
  const MarginStats& m = Measure(margin);
  ASSERT_GE(m.fit.found_tags, m.fit.truth_tags * 95 / 100) << "the fit declined too many tags";
  ASSERT_GE(m.detector.found_tags, m.detector.truth_tags * 3 / 4);
  ASSERT_GE(m.tracking.found_tags, m.tracking.truth_tags * 3 / 4);
  // The fit alone also has the quarter of the tags libapriltag does not find
  // at these tilts, the most tilted: their acute corners carry the inward
  // bias the fit has at tilts >= 60 degrees whatever the margin (-0.01 to
  // -0.05 px at corners under 80 degrees; docs/detection.md). Measured
  // -0.0019, -0.0023, -0.0030 px at margins 1-3 (before this margin's fix:
  // -0.0214, -0.0022, -0.0026), hence 0.004 for it.
  ExpectTargets(m.fit, "fit", margin, 0.004);
  ExpectTargets(m.detector, "detector", margin);
  ExpectTargets(m.tracking, "tracking", margin);
}

// The quick check (and the sanitizers' run of the textured raster): one
// 640x480 frame, 20 tags of 32 px tilted up to 40 degrees at margin 1 over a
// texture. Measured bias +0.0005 px, median 0.006; the old fit -0.0118,
// median 0.013.
TEST(CornerMargin, OneModuleOfWhiteOverTextureIsUnbiased) {
  const std::vector<PlacedTag> truth = RandomTagPlacements(640, 480, 20, 32.0, 40.0, 77);
  TagRenderOptions render;
  render.blur_sigma_px = 0.7;
  render.noise_sigma = 1.0;
  render.margin_modules = 1.0;
  render.texture_contrast = 100.0;
  render.background = 110.0;
  render.tag_shade_variation = 0.3;
  const Result<cv::Mat> image = RenderTags("tag36h11", 640, 480, truth, render);
  ASSERT_TRUE(image.has_value()) << image.error().message;
  std::mt19937 rng(3);
  const DetectionSet fitted = testing::FitFromMovedTruth(*image, truth, rng);
  CornerStats stats;
  testing::AccumulateCornerStats(truth, fitted, &stats);
  std::printf("margin 1 over texture, 32 px: %s\n", stats.Summary().c_str());
  ASSERT_EQ(stats.found_tags, stats.truth_tags);
  // 80 corners of ~0.01 px scatter: the mean to ~0.0015 px.
  EXPECT_LE(std::abs(stats.bias), 0.005);
  EXPECT_LE(stats.Median(), 0.03);
}

TEST(CornerMarginSlow, OneModuleOfWhite) { ExpectMarginTargets(1.0); }
TEST(CornerMarginSlow, TwoModulesOfWhite) { ExpectMarginTargets(2.0); }
TEST(CornerMarginSlow, ThreeModulesOfWhite) { ExpectMarginTargets(3.0); }

}  // namespace
}  // namespace tagsfm
