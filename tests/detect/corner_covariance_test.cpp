// Each corner's covariance from the edge fit (TagDetection::
// corner_covariance) against its true error, on rendered frames whose
// conditions all vary: tag size, tilt, blur, noise, white margin, texture,
// contrast and lens. A covariance that describes the error gives the
// normalized squared error e^T C^-1 e a mean of 2 (two degrees of freedom),
// and corners it calls worse must be worse by as much.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <map>
#include <vector>

#include <Eigen/Dense>
#include <gtest/gtest.h>

#include "tagsfm/detect/synthetic_tags.h"
#include "tagsfm/detect/tag_detector.h"
#include "test_camera.h"

namespace tagsfm {
namespace {

struct FrameSpec {
  double side_px;
  double tilt_deg;
  double blur;
  double noise;
  double margin;
  double texture;
  double contrast;  // white - black, grey levels
  bool lens;
};

// Every field differs between frames; none is the same for all.
constexpr std::array<FrameSpec, 8> kFrames = {{
    {16.0, 40.0, 0.6, 2.0, 1.0, 80.0, 190.0, false},
    {20.0, 70.0, 0.8, 4.0, 2.0, 100.0, 150.0, true},
    {24.0, 60.0, 1.2, 2.0, 1.0, 60.0, 120.0, false},
    {28.0, 30.0, 0.5, 6.0, 3.0, 120.0, 190.0, true},
    {32.0, 70.0, 1.6, 3.0, 1.0, 40.0, 170.0, false},
    {40.0, 50.0, 0.7, 1.0, 2.0, 90.0, 100.0, false},
    {48.0, 65.0, 2.0, 5.0, 1.0, 110.0, 180.0, true},
    {22.0, 55.0, 1.0, 3.0, 3.0, 70.0, 140.0, false},
}};

CameraModel Lens() {
  CameraModel camera = testing::PinholeCamera(800, 600, 600.0, 399.5, 299.5);
  camera.distortion = {-0.2, 0.05, 0.0003, -0.0002, 0.0};
  return camera;
}

struct CornerSample {
  Eigen::Vector2d error;
  Eigen::Matrix2d covariance;
  double sigma() const { return std::sqrt(0.5 * covariance.trace()); }
};

// One frame's corners within 0.5 px of the truth (a tag the fit declined
// keeps libapriltag's corners, 1-2 px off), and how many had no covariance.
struct FrameCorners {
  std::vector<CornerSample> samples;
  int without_covariance = 0, gross = 0;
  double predicted = 0, actual = 0;  // RMS of the predicted sigma, RMS error per axis
};

FrameCorners MeasureFrame(const FrameSpec& spec, int index) {
  static const CameraModel lens = Lens();
  FrameCorners out;
  std::vector<PlacedTag> placed = RandomTagPlacements(lens.width, lens.height, 30, spec.side_px, spec.tilt_deg, 40 + index);
  TagRenderOptions render;
  render.blur_sigma_px = spec.blur;
  render.noise_sigma = spec.noise;
  render.margin_modules = spec.margin;
  render.texture_contrast = spec.texture;
  render.black = 0.5 * (250.0 - spec.contrast);
  render.white = render.black + spec.contrast;
  render.background = 0.5 * (render.black + render.white);
  render.tag_shade_variation = 0.3;
  render.seed = static_cast<std::uint64_t>(500 + index);
  render.camera = spec.lens ? &lens : nullptr;
  const Result<cv::Mat> image = RenderTags("tag36h11", lens.width, lens.height, placed, render);
  EXPECT_TRUE(image.has_value()) << image.error().message;
  if (!image) return out;
  if (spec.lens) {
    for (PlacedTag& tag : placed) {
      for (Eigen::Vector2d& c : tag.corners) {
        c = lens.Project(Eigen::Vector3d((c.x() - lens.cx) / lens.fx, (c.y() - lens.cy) / lens.fy, 1.0));
      }
    }
  }
  TagDetectorOptions options;
  if (spec.lens) options.camera = lens;
  auto detector = TagDetector::Create(options);
  EXPECT_TRUE(detector.has_value());
  if (!detector) return out;
  auto detections = (*detector)->Detect(*image, static_cast<FrameId>(index));
  EXPECT_TRUE(detections.has_value());
  if (!detections) return out;
  std::map<TagId, const PlacedTag*> truth;
  for (const PlacedTag& t : placed) truth[t.id] = &t;
  double e2 = 0, s2 = 0;
  for (const TagDetection& tag : detections->tags) {
    const auto it = truth.find(tag.id);
    if (it == truth.end()) continue;
    for (int k = 0; k < 4; ++k) {
      const CornerSample sample{tag.corners[k] - it->second->corners[k], tag.corner_covariance[k]};
      if (!(sample.covariance.determinant() > 0)) {
        ++out.without_covariance;
      } else if (sample.error.norm() > 0.5) {
        ++out.gross;
      } else {
        out.samples.push_back(sample);
        e2 += 0.5 * sample.error.squaredNorm();
        s2 += sample.sigma() * sample.sigma();
      }
    }
  }
  const double n = static_cast<double>(out.samples.size());
  if (n > 0) {
    out.predicted = std::sqrt(s2 / n);
    out.actual = std::sqrt(e2 / n);
  }
  return out;
}

// Measured 2026-12-06: the frames' actual RMS per axis runs from 0.008 px
// (40 px tags, noise 1) to 0.085 px (48 px at 65 degrees, blur 2, noise 5),
// the predicted sigma from 0.007 to 0.047 px; actual / predicted 0.97-1.17
// at margins 2-3 and 1.6-1.8 at margin 1 over texture (the texture just past
// the one-module ring leaves residuals correlated along the edge, which a
// covariance from independent pixels does not see). Pooled, e^T C^-1 e has
// a mean of 3.8 (2 if exact). So the covariance ranks corners as their
// errors do, to within a factor 2 in sigma; the adjustment's variance
// factor takes its common scale. Bounds: each frame within 0.7-2.0, the
// worst frame's predicted sigma at least 4x the best's.
TEST(CornerCovarianceSlow, FollowsTheCornersErrorAcrossConditions) {
  double lowest_actual = 1e9, highest_actual = 0, lowest_predicted = 1e9, highest_predicted = 0;
  double q_sum = 0;
  int corners = 0;
  for (size_t f = 0; f < kFrames.size(); ++f) {
    const FrameCorners frame = MeasureFrame(kFrames[f], static_cast<int>(f));
    std::printf("frame %zu: %zu corners, predicted sigma %.4f px, actual RMS per axis %.4f px (ratio %.2f)\n", f,
                frame.samples.size(), frame.predicted, frame.actual, frame.actual / frame.predicted);
    // Every corner the detector refined has one.
    EXPECT_EQ(frame.without_covariance, 0) << "frame " << f;
    EXPECT_LE(frame.gross, 4) << "frame " << f;
    if (frame.samples.size() < 20) continue;  // too few for an RMS
    EXPECT_GT(frame.actual / frame.predicted, 0.7) << "frame " << f;
    EXPECT_LT(frame.actual / frame.predicted, 2.0) << "frame " << f;
    lowest_actual = std::min(lowest_actual, frame.actual);
    highest_actual = std::max(highest_actual, frame.actual);
    lowest_predicted = std::min(lowest_predicted, frame.predicted);
    highest_predicted = std::max(highest_predicted, frame.predicted);
    for (const CornerSample& s : frame.samples) q_sum += s.error.dot(s.covariance.inverse() * s.error);
    corners += static_cast<int>(frame.samples.size());
  }
  ASSERT_GT(corners, 300);
  std::printf("%d corners: mean e^T C^-1 e %.2f (2 if exact); actual %.4f-%.4f px, predicted %.4f-%.4f px\n", corners,
              q_sum / corners, lowest_actual, highest_actual, lowest_predicted, highest_predicted);
  // The conditions differ enough that the covariance must tell corners apart.
  EXPECT_GT(highest_predicted, 4.0 * lowest_predicted);
}

}  // namespace
}  // namespace tagsfm
