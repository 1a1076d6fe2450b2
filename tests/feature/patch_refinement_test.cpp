// Least-squares patch matching against exact warps: both images are
// rendered from one continuous texture (Gaussian blobs, integrated over
// each pixel), the second through a known affine map and a brightness and
// contrast change, then blurred and given noise; the fit must find the true
// position of the reference pixel from a start 0.7 px and several percent
// of affine away.
#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <iostream>
#include <map>
#include <random>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "tagsfm/feature/patch_refinement.h"
#include "tagsfm/feature/track_refinement.h"
#include "test_camera.h"

namespace tagsfm {
namespace {

struct Blob {
  Eigen::Vector2d centre;
  double sigma, amplitude;
};

// A texture on the plane: blobs of radius `size` on a mid grey.
std::vector<Blob> MakeTexture(double size, unsigned seed, double extent) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> pos(-extent, extent), amp(-90, 90), spread(0.6, 1.4);
  std::vector<Blob> blobs;
  const int count = static_cast<int>(4 * extent * extent / (size * size) * 0.6);
  for (int i = 0; i < count; ++i) blobs.push_back({{pos(rng), pos(rng)}, size * spread(rng), amp(rng)});
  return blobs;
}

double TextureAt(const std::vector<Blob>& blobs, const Eigen::Vector2d& u) {
  double v = 128;
  for (const Blob& b : blobs) {
    const double d2 = (u - b.centre).squaredNorm();
    if (d2 < 16 * b.sigma * b.sigma) v += b.amplitude * std::exp(-0.5 * d2 / (b.sigma * b.sigma));
  }
  return v;
}

// The texture blurred by a Gaussian of `blur` texture units: a blob stays a
// blob, wider and fainter (the convolution of two Gaussians), so both
// images of a pair are exact warps of one blurred surface.
std::vector<Blob> Blurred(std::vector<Blob> blobs, double blur) {
  for (Blob& b : blobs) {
    const double s2 = b.sigma * b.sigma + blur * blur;
    b.amplitude *= b.sigma * b.sigma / s2;
    b.sigma = std::sqrt(s2);
  }
  return blobs;
}

// `image` (CV_64F grey values) plus Gaussian noise from `seed`, rounded to
// 8 bits.
cv::Mat WithNoise(const cv::Mat& image, double noise, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> n(0, noise);
  cv::Mat out(image.rows, image.cols, CV_8U);
  for (int y = 0; y < image.rows; ++y) {
    for (int x = 0; x < image.cols; ++x) out.at<std::uint8_t>(y, x) = cv::saturate_cast<std::uint8_t>(image.at<double>(y, x) + n(rng));
  }
  return out;
}

// An image of `size` pixels whose pixel x sees texture point linear * x +
// shift, averaged over 2 x 2 samples per pixel, times `gain` plus `offset`,
// with Gaussian noise.
cv::Mat Render(const std::vector<Blob>& blobs, int size, const Eigen::Matrix2d& linear, const Eigen::Vector2d& shift, double gain,
               double offset, double noise, unsigned seed) {
  cv::Mat image(size, size, CV_64F);
  for (int y = 0; y < size; ++y) {
    for (int x = 0; x < size; ++x) {
      double sum = 0;
      for (double sy : {-0.25, 0.25}) {
        for (double sx : {-0.25, 0.25}) sum += TextureAt(blobs, linear * Eigen::Vector2d(x + sx, y + sy) + shift);
      }
      image.at<double>(y, x) = gain * sum / 4 + offset;
    }
  }
  return WithNoise(image, noise, seed);
}

struct Case {
  double blob_px;  // texture scale in reference pixels
  double blur, noise;
  double rotation_deg, scale, shear;
  double gain, offset;
};

// One case's two images: the texture from `seed`, the reference's and the
// target's noise from the next two seeds of `noise_seeds`. Reference: pixel x sees texture point x - 32. Target: pixel y
// sees the texture point of reference pixel p = c_ref + A^-1 (y - c_t).
struct PatchPair {
  cv::Mat reference, target;
  Eigen::Vector2d ref_centre{31.3, 32.6}, target_centre{30.8, 31.1};
  Eigen::Matrix2d affine;  // A: the true warp
};

PatchPair MakePatchPair(const Case& c, unsigned seed, std::array<unsigned, 2> noise_seeds) {
  constexpr int kSize = 64;
  PatchPair pair;
  const std::vector<Blob> blobs = Blurred(MakeTexture(c.blob_px, seed, 40), c.blur);
  const double r = c.rotation_deg * M_PI / 180;
  pair.affine << c.scale * std::cos(r), -c.scale * std::sin(r) + c.shear, c.scale * std::sin(r), c.scale * std::cos(r);
  const Eigen::Matrix2d a_inv = pair.affine.inverse();
  const Eigen::Vector2d to_texture(-32, -32);
  pair.reference = Render(blobs, kSize, Eigen::Matrix2d::Identity(), to_texture, 1, 0, c.noise, noise_seeds[0]);
  pair.target = Render(blobs, kSize, a_inv, pair.ref_centre - a_inv * pair.target_centre + to_texture, c.gain, c.offset,
                       c.noise, noise_seeds[1]);
  return pair;
}

// Error of the fitted centre against the truth, or -1 when the fit was
// refused (default options).
double FitError(const Case& c, unsigned seed) {
  const PatchPair pair = MakePatchPair(c, seed, {seed + 1, seed + 2});
  PatchWarp start;
  start.centre = pair.target_centre + Eigen::Vector2d(0.5, -0.5);  // 0.7 px off
  Eigen::Matrix2d off;
  off << 1.04, 0.03, -0.02, 0.97;  // the predicted warp a few percent wrong
  start.affine = pair.affine * off;
  const std::optional<PatchFit> fit = RefinePatch(pair.reference, pair.ref_centre, pair.target, start, {});
  if (!fit) return -1;
  return (fit->warp.centre - pair.target_centre).norm();
}

// Over textures, blurs, noise levels and warps: the localisation the
// triangulation needs. With noise s on both images and grey gradients g
// over the (2h+1)^2 = 225 pixels, the shift's standard deviation is about
// s sqrt(2) / (g sqrt(225)); for the weakest case (noise 5, blur 1.5,
// coarse blobs: g ~ 5-10 grey/px) that is 0.05-0.1 px, so the bound on the
// mean is 0.05 px and on the worst 0.2 px per 2 grey levels of noise (the
// synth default); with no noise the fit must be
// exact to what the 2 x 2 pixel integration and bilinear resampling leave
// (0.02 px). SIFT, for comparison, is 0.3-0.4 px off.
TEST(PatchRefinement, FindsExactWarpsToHundredthsOfAPixel) {
  const std::vector<Case> cases = {
      {3, 0.7, 0, 0, 1, 0, 1, 0},        // no noise
      {3, 0.7, 2, 0, 1, 0, 1, 0},        // the synth default noise
      {3, 0.5, 2, 10, 1, 0, 1, 0},       // rotation
      {3, 1.0, 2, -5, 0.8, 0, 1, 0},     // zoom out
      {5, 1.5, 2, 0, 1.2, 0.1, 1, 0},    // zoom in, shear, coarse texture, blur
      {2, 0.7, 2, 3, 0.9, -0.08, 0.6, 30},  // darker, brighter floor, fine texture
      {4, 1.0, 5, 8, 1.1, 0.05, 0.85, 25},  // heavy noise, less contrast (more clips the blobs at 255 and biases the fit)
  };
  for (size_t k = 0; k < cases.size(); ++k) {
    double sum = 0, worst = 0;
    int failed = 0;
    constexpr int kSeeds = 4;
    for (unsigned seed = 0; seed < kSeeds; ++seed) {
      const double e = FitError(cases[k], 100 * static_cast<unsigned>(k) + seed);
      if (e < 0) {
        ++failed;
        continue;
      }
      sum += e;
      worst = std::max(worst, e);
    }
    const double mean = sum / (kSeeds - failed);
    std::cout << "case " << k << ": mean " << mean << " px, worst " << worst << " px, failed " << failed << "\n";
    // A fit whose own predicted sigma is too large is refused (heavy noise
    // on a weak texture); at the synth default noise none may be.
    EXPECT_LE(failed, cases[k].noise <= 2 ? 0 : kSeeds / 2) << "case " << k;
    // The shift's noise grows with the images' noise: bounds per 2 grey
    // levels of it.
    const double per_2 = std::max(cases[k].noise, 2.0) / 2;
    EXPECT_LT(mean, cases[k].noise == 0 ? 0.02 : 0.05 * per_2) << "case " << k;
    EXPECT_LT(worst, cases[k].noise == 0 ? 0.03 : 0.2 * per_2) << "case " << k;
  }
}

// Gauss-Newton on bilinearly sampled, noisy grey values need not settle
// A fit that has used up its iterations without a step under converged_px
// counts when its last step is a small part of its own sigma (which then
// holds the step too). Here converged_px is out of reach (1e-9 px) on
// noisy patches, so most fits end by the rule: each must lie where the
// same fit settles given 50 iterations and the usual 0.01 px, to a small
// part of its sigma (median), and the fits stopped by the rule must be as
// far from the truth as the settled ones (RMS of error / sigma within 5 %);
// without the rule few fits end at all.
TEST(PatchRefinement, AFitOutOfIterationsCountsWhenItsLastStepIsSmallAgainstItsSigma) {
  const std::vector<Case> cases = {
      {3, 1.0, 6, 0, 1, 0, 1, 0},
      {4, 1.0, 5, 8, 1.1, 0.05, 0.85, 25},
  };
  PatchRefinementOptions by_sigma;
  by_sigma.converged_px = 1e-9;
  PatchRefinementOptions absolute_only = by_sigma;
  absolute_only.converged_sigma_fraction = 0;
  PatchRefinementOptions settled;
  settled.max_iterations = 50;
  for (const Case& c : cases) {
    int accepted = 0, accepted_absolute = 0;
    std::vector<double> from_settled;  // distance to the settled fit / sigma
    double stopped_sq = 0, settled_sq = 0;  // (error against the truth / sigma)^2
    constexpr int kSeeds = 32;
    for (unsigned seed = 0; seed < kSeeds; ++seed) {
      const PatchPair pair = MakePatchPair(c, 500 + seed, {600 + seed, 700 + seed});
      PatchWarp start;
      start.centre = pair.target_centre + Eigen::Vector2d(0.5, -0.5);
      start.affine = pair.affine;
      const auto fit_with = [&](const PatchRefinementOptions& options) {
        return RefinePatch(pair.reference, pair.ref_centre, pair.target, start, options);
      };
      if (fit_with(absolute_only)) ++accepted_absolute;
      const auto fit = fit_with(by_sigma);
      if (!fit) continue;
      ++accepted;
      const auto reference_fit = fit_with(settled);
      ASSERT_TRUE(reference_fit.has_value()) << "seed " << seed << ": settles with more iterations";
      from_settled.push_back((fit->warp.centre - reference_fit->warp.centre).norm() / fit->sigma_px);
      stopped_sq += std::pow((fit->warp.centre - pair.target_centre).norm() / fit->sigma_px, 2);
      settled_sq += std::pow((reference_fit->warp.centre - pair.target_centre).norm() / reference_fit->sigma_px, 2);
    }
    ASSERT_FALSE(from_settled.empty());
    std::sort(from_settled.begin(), from_settled.end());
    const double median = from_settled[from_settled.size() / 2];
    const double error_ratio = std::sqrt(stopped_sq / settled_sq);
    std::cout << "noise " << c.noise << ": " << accepted << " of " << kSeeds << " fits by the sigma rule (" << accepted_absolute
              << " without it), from the settled fit " << median << " sigma median, " << from_settled.back()
              << " worst; error / sigma against the settled fits' " << error_ratio << "\n";
    EXPECT_GE(accepted, kSeeds * 3 / 4) << "noise " << c.noise;
    EXPECT_LE(accepted_absolute, kSeeds / 4) << "noise " << c.noise;
    EXPECT_LT(median, 0.15) << "noise " << c.noise;
    EXPECT_NEAR(error_ratio, 1.0, 0.05) << "noise " << c.noise;
  }
}

// The first steps on every other pixel (sparse_until_px) must end where
// the fit on every pixel ends, for a quarter of the work per step: over
// textures, blurs, noise, warps and starts up to 1.4 px off, both accept the
// same fits (a sparse start may land a borderline fit either way, so one in
// twenty may differ), their centres agree to a small part of the sigma
// (the last steps are the same full-patch steps) and are as far from the
// truth, and the sparse start, nearer the minimum, leaves no more counted
// steps to take (the full-patch ones and the sparse one that ends the
// sparse steps). (What it saves is the steps of the fits that
// are refused: the triangulation's time in docs/features.md.)
TEST(PatchRefinement, SparseFirstStepsEndWhereEveryPixelFitsEnd) {
  const std::vector<Case> cases = {
      {3, 0.7, 2, 0, 1, 0, 1, 0},
      {3, 0.5, 2, 10, 1, 0, 1, 0},
      {3, 1.0, 2, -5, 0.8, 0, 1, 0},
      {5, 1.5, 2, 0, 1.2, 0.1, 1, 0},
      {2, 0.7, 2, 3, 0.9, -0.08, 0.6, 30},
      {4, 1.0, 5, 8, 1.1, 0.05, 0.85, 25},
  };
  PatchRefinementOptions sparse, every_pixel;
  ASSERT_GT(sparse.sparse_until_px, 0) << "the default starts sparse";
  every_pixel.sparse_until_px = 0;
  int both = 0, differ = 0, sparse_iterations = 0, full_iterations = 0;
  std::vector<double> apart;  // distance between the two fits / sigma
  double sparse_sq = 0, full_sq = 0;  // (error against the truth / sigma)^2
  for (size_t k = 0; k < cases.size(); ++k) {
    for (unsigned seed = 0; seed < 8; ++seed) {
      const unsigned s = 1000 + 100 * static_cast<unsigned>(k) + seed;
      const PatchPair pair = MakePatchPair(cases[k], s, {s + 50, s + 60});
      const double angle = 0.8 * seed;
      PatchWarp start;
      start.centre = pair.target_centre + (0.4 + 0.15 * seed) * Eigen::Vector2d(std::cos(angle), std::sin(angle));
      Eigen::Matrix2d off;
      off << 1.04, 0.03, -0.02, 0.97;
      start.affine = pair.affine * off;
      const auto a = RefinePatch(pair.reference, pair.ref_centre, pair.target, start, sparse);
      const auto b = RefinePatch(pair.reference, pair.ref_centre, pair.target, start, every_pixel);
      if (a.has_value() != b.has_value()) ++differ;
      if (!a || !b) continue;
      ++both;
      sparse_iterations += a->iterations;
      full_iterations += b->iterations;
      apart.push_back((a->warp.centre - b->warp.centre).norm() / b->sigma_px);
      sparse_sq += std::pow((a->warp.centre - pair.target_centre).norm() / a->sigma_px, 2);
      full_sq += std::pow((b->warp.centre - pair.target_centre).norm() / b->sigma_px, 2);
    }
  }
  ASSERT_GE(both, 36);  // of 48
  std::sort(apart.begin(), apart.end());
  const double error_ratio = std::sqrt(sparse_sq / full_sq);
  std::cout << both << " fits by both, " << differ << " by one; apart " << apart[apart.size() / 2] << " sigma median, "
            << apart.back() << " worst; error / sigma against every pixel's " << error_ratio << "; counted steps "
            << sparse_iterations << " against " << full_iterations << "\n";
  EXPECT_LE(differ, 2);
  EXPECT_LT(apart[apart.size() / 2], 0.1);
  EXPECT_LT(apart.back(), 0.5);
  EXPECT_NEAR(error_ratio, 1.0, 0.05);
  EXPECT_LE(sparse_iterations, full_iterations);
}

// A patch of another texture is refused (correlation), as is a flat patch
// (the centre is not located: its predicted sigma is large).
TEST(PatchRefinement, RefusesWrongAndFlatPatches) {
  const std::vector<Blob> a = Blurred(MakeTexture(3, 1, 40), 0.7), b = Blurred(MakeTexture(3, 2, 40), 0.7);
  const cv::Mat ref = Render(a, 64, Eigen::Matrix2d::Identity(), {-32, -32}, 1, 0, 2, 3);
  const cv::Mat other = Render(b, 64, Eigen::Matrix2d::Identity(), {-32, -32}, 1, 0, 2, 4);
  PatchWarp start;
  start.centre = {32, 32};
  EXPECT_FALSE(RefinePatch(ref, {32, 32}, other, start, {}).has_value());
  const cv::Mat flat = Render({}, 64, Eigen::Matrix2d::Identity(), {0, 0}, 1, 0, 2, 5);
  const cv::Mat flat_again = Render({}, 64, Eigen::Matrix2d::Identity(), {0, 0}, 1, 0, 2, 6);
  EXPECT_FALSE(RefinePatch(flat, {32, 32}, flat_again, start, {}).has_value());
  // The same texture, shifted by a known amount, is found with the defaults.
  const cv::Mat shifted = Render(a, 64, Eigen::Matrix2d::Identity(), {-32.4, -31.7}, 1, 0, 2, 7);
  const std::optional<PatchFit> fit = RefinePatch(ref, {32, 32}, shifted, start, {});
  ASSERT_TRUE(fit.has_value());
  EXPECT_LT((fit->warp.centre - Eigen::Vector2d(32.4, 31.7)).norm(), 0.05);
  EXPECT_GT(fit->correlation, 0.95);
}

// A straight grey edge through `through` with unit normal at `normal_deg`,
// blurred by a Gaussian of `blur` px, dark 70 to bright 180, with noise.
cv::Mat RenderEdge(int size, const Eigen::Vector2d& through, double normal_deg, double blur, double noise, unsigned seed) {
  const double a = normal_deg * M_PI / 180;
  const Eigen::Vector2d normal(std::cos(a), std::sin(a));
  std::mt19937 rng(seed);
  std::normal_distribution<double> n(0, noise);
  cv::Mat out(size, size, CV_8U);
  for (int y = 0; y < size; ++y) {
    for (int x = 0; x < size; ++x) {
      const double d = normal.dot(Eigen::Vector2d(x, y) - through);
      const double v = 70 + 110 * 0.5 * (1 + std::erf(d / (std::sqrt(2.0) * blur)));
      out.at<std::uint8_t>(y, x) = cv::saturate_cast<std::uint8_t>(v + n(rng));
    }
  }
  return out;
}

// A patch on a straight edge is located across the edge only: a free fit
// slides along it and is refused. Held to a line the edge crosses (the
// epipolar line, here the image's x axis), the fit finds the crossing; a
// line known to sigma_a across itself adds sigma_a / tan(angle between
// edge and line) along it, so an edge running nearly along the line is
// refused. Edges at 30-150 degrees to the line, two blurs, noise 2.
TEST(PatchRefinement, AnEdgeIsFoundAlongALineItCrosses) {
  const Eigen::Vector2d reference_pixel(32, 32.3);
  unsigned seed = 1;
  for (const double edge_deg : {30.0, 60.0, 90.0, 125.0, 150.0}) {
    for (const double blur : {0.8, 1.5}) {
      const double shift = 2.3;  // the edge lies 2.3 px further right in the target, along the line
      const cv::Mat reference = RenderEdge(64, reference_pixel, edge_deg + 90, blur, 2, ++seed);
      const cv::Mat target = RenderEdge(64, reference_pixel + Eigen::Vector2d(shift, 0), edge_deg + 90, blur, 2, ++seed);
      const Eigen::Vector2d truth = reference_pixel + Eigen::Vector2d(shift, 0);
      PatchWarp start;
      start.centre = truth + Eigen::Vector2d(-1.1, 0);  // on the line, 1.1 px short
      EXPECT_FALSE(RefinePatch(reference, reference_pixel, target, start, {}).has_value()) << edge_deg << " " << blur;
      const std::optional<PatchFit> exact = RefinePatch(reference, reference_pixel, target, start, {}, PatchLine{{1, 0}, 0.0});
      ASSERT_TRUE(exact.has_value()) << edge_deg << " " << blur;
      EXPECT_LT((exact->warp.centre - truth).norm(), 0.05) << edge_deg << " " << blur;
      EXPECT_NEAR(exact->warp.centre.y(), truth.y(), 1e-9);  // it stays on the line
      const double across = 0.05;
      PatchRefinementOptions loose;
      loose.max_sigma_px = 1;
      const std::optional<PatchFit> uncertain =
          RefinePatch(reference, reference_pixel, target, start, loose, PatchLine{{1, 0}, across});
      ASSERT_TRUE(uncertain.has_value());
      const double along_per_across = 1 / std::tan(edge_deg * M_PI / 180);
      const double expected = std::hypot(exact->sigma_px, along_per_across * across);
      EXPECT_NEAR(uncertain->sigma_px, expected, 0.1 * expected) << edge_deg << " " << blur;
    }
  }
  // An edge 8 degrees off the line: 0.05 px across is 0.36 px along.
  const cv::Mat reference = RenderEdge(64, reference_pixel, 98, 1.0, 2, 90);
  const cv::Mat target = RenderEdge(64, reference_pixel + Eigen::Vector2d(2, 0), 98, 1.0, 2, 91);
  PatchWarp start;
  start.centre = reference_pixel + Eigen::Vector2d(1, 0);
  EXPECT_FALSE(RefinePatch(reference, reference_pixel, target, start, {}, PatchLine{{1, 0}, 0.05}).has_value());
}

TEST(PatchRefinement, OptionsAndPatchesNearTheBorderAreChecked) {
  PatchRefinementOptions options;
  options.half_window = 1;
  EXPECT_NE(options.Check().error().message.find("half_window"), std::string::npos);
  options = {};
  options.converged_sigma_fraction = 1.5;
  EXPECT_NE(options.Check().error().message.find("converged_sigma_fraction"), std::string::npos);
  options = {};
  options.reference_attempts = 0;
  EXPECT_NE(options.Check().error().message.find("reference_attempts"), std::string::npos);
  options = {};
  options.tilt_retries = -1;
  EXPECT_NE(options.Check().error().message.find("tilt_retries"), std::string::npos);
  options = {};
  options.tilt_step_deg = 90;
  EXPECT_NE(options.Check().error().message.find("tilt_step_deg"), std::string::npos);
  const cv::Mat image(40, 40, CV_8U, cv::Scalar(100));
  PatchWarp start;
  start.centre = {20, 20};
  EXPECT_FALSE(RefinePatch(image, {3, 20}, image, start, {}).has_value());  // patch leaves the reference
  start.centre = {38, 20};
  EXPECT_FALSE(RefinePatch(image, {20, 20}, image, start, {}).has_value());  // and the target
}

// The predicted warp is the plane's homography to first order: a camera
// sliding along a fronto-parallel plane sees it unwarped, one moved from 2 m
// to 1.5 m sees it 4/3 larger, and one turned about the plane's vertical
// axis by 20 degrees sees it compressed across by about cos 20.
TEST(PatchRefinement, PredictedAffineIsThePlanesHomography) {
  const CameraModel camera = testing::PinholeCamera(1280, 720, 1000, 639.5, 359.5);
  const Eigen::Vector3d point(0.1, -0.05, 2.0), normal(0, 0, -1);
  const Rigid3d reference;
  const Rigid3d slid(Eigen::Quaterniond::Identity(), Eigen::Vector3d(-0.2, 0.1, 0));
  EXPECT_LT((PredictPatchAffine(point, normal, reference, slid, camera) - Eigen::Matrix2d::Identity()).norm(), 1e-6);
  const Rigid3d closer(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0, 0, -0.5));
  EXPECT_LT((PredictPatchAffine(point, normal, reference, closer, camera) - 4.0 / 3.0 * Eigen::Matrix2d::Identity()).norm(), 1e-6);
  // Turned round the point (at the same distance): the image's x axis
  // shrinks by cos 20 (to the point's small offset from the axis).
  const double a = 20 * M_PI / 180;
  const Eigen::Quaterniond turn(Eigen::AngleAxisd(a, Eigen::Vector3d::UnitY()));
  const Rigid3d turned(turn, point - (turn * point));
  const Eigen::Matrix2d affine = PredictPatchAffine(point, normal, reference, turned, camera);
  EXPECT_NEAR(affine(0, 0), std::cos(a), 0.02);
  EXPECT_NEAR(affine(1, 1), 1.0, 0.02);
}

// A track of `truth` seen by every camera of `poses`, each view's SIFT
// pixel `sift_error(frame)` off its projection, and its first triangulation
// (at the truth).
struct TrackAndPoint {
  FeatureTrack track;
  FeaturePoint point;
};

TrackAndPoint SiftTrack(TrackId id, const Eigen::Vector3d& truth, const PoseMap& poses, const CameraModel& camera,
                        const std::function<Eigen::Vector2d(FrameId)>& sift_error) {
  TrackAndPoint out;
  out.track.id = id;
  out.point.track = id;
  out.point.position = truth;
  for (const auto& [frame, pose] : poses) {
    const Eigen::Vector2d pixel = camera.Project(pose * truth) + sift_error(frame);
    out.track.observations.push_back({frame, static_cast<int>(frame), pixel, {0, 0, 0}, 0});
    out.point.observations.emplace_back(frame, pixel);
  }
  return out;
}

// `count` cameras side by side along x, `step` m apart, all looking along z.
PoseMap CamerasAlongX(int count, double step) {
  PoseMap poses;
  for (FrameId k = 0; k < count; ++k) {
    poses[k] = Rigid3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(-step * static_cast<double>(k), 0, 0));
  }
  return poses;
}

// The keyframes' images at full size only (no coarser levels); `images`
// must outlive the lookup.
KeyframeImageLookup FullSizeOnly(const std::map<FrameId, cv::Mat>& images) {
  return [&images](FrameId frame, int level) { return level == 0 ? &images.at(frame) : nullptr; };
}

// Three cameras side by side (1 px apart in the image) over a textured
// fronto-parallel plane; the middle one is the reference. A view whose
// image is flat refuses its fit: it stays at its own pixel with the
// detector's noise when asked (unrefined_sigma_px), or is dropped. A track
// left with no fit at all is kept only with three or more views: two
// unrefined views cannot tell a wrong match from a right one.
TEST(TrackRefinement, ARefusedFitKeepsItsPixelAtTheDetectorsNoise) {
  const CameraModel camera = testing::PinholeCamera(64, 64, 100, 31.5, 31.5);
  const double depth = 2.0, step = 0.02;  // f * step / depth = 1 px between cameras
  const std::vector<Blob> texture = Blurred(MakeTexture(3, 11, 40), 0.7);
  std::map<FrameId, cv::Mat> textured, flat;
  const PoseMap poses = CamerasAlongX(3, step);
  for (FrameId k = 0; k < 3; ++k) {
    const double t = step * static_cast<double>(k);
    textured[k] = Render(texture, 64, Eigen::Matrix2d::Identity(), {-31.5 + 100 * t / depth, -31.5}, 1, 0, 1, 20 + k);
    flat[k] = Render({}, 64, Eigen::Matrix2d::Identity(), {0, 0}, 1, 0, 1, 30 + k);
  }
  const Eigen::Vector3d truth((31.3 - 31.5) * depth / 100 + step, (32.6 - 31.5) * depth / 100, depth);
  // SIFT's pixels, 0.3 px off the truth in the non-reference views.
  TrackAndPoint sift = SiftTrack(7, truth, poses, camera, [](FrameId k) { return Eigen::Vector2d(k == 1 ? 0 : 0.3, 0); });
  FeatureTrack& track = sift.track;
  FeaturePoint& point = sift.point;
  const auto refine = [&](std::map<FrameId, const cv::Mat*> images, double unrefined_sigma_px, const FeatureTrack& t) {
    const KeyframeImageLookup image_of = [&](FrameId frame, int level) { return level == 0 ? images.at(frame) : nullptr; };
    return RefineTrackViews(t, point, poses, image_of, camera, {}, unrefined_sigma_px);
  };

  // Frame 2 flat: frame 0 is fitted to the truth, frame 2 keeps its pixel.
  const FeatureTrack one_refused = refine({{0, &textured[0]}, {1, &textured[1]}, {2, &flat[2]}}, 0.5, track);
  ASSERT_EQ(one_refused.observations.size(), 3u);
  EXPECT_LT((one_refused.observations[0].pixel - camera.Project(poses.at(0) * truth)).norm(), 0.1);
  EXPECT_LT(one_refused.observations[0].sigma_px, 0.1);
  EXPECT_EQ(one_refused.observations[2].pixel, track.observations[2].pixel);
  EXPECT_EQ(one_refused.observations[2].sigma_px, 0.5);
  // Asked to drop refused views: two are left.
  const FeatureTrack dropped = refine({{0, &textured[0]}, {1, &textured[1]}, {2, &flat[2]}}, 0.0, track);
  ASSERT_EQ(dropped.observations.size(), 2u);
  EXPECT_EQ(dropped.observations[1].frame, 0 + 1);
  // No fit: three views are kept unrefined, two are not.
  const std::map<FrameId, const cv::Mat*> none_fit{{0, &flat[0]}, {1, &textured[1]}, {2, &flat[2]}};
  const FeatureTrack three_unrefined = refine(none_fit, 0.5, track);
  ASSERT_EQ(three_unrefined.observations.size(), 3u);
  for (const TrackObservation& o : three_unrefined.observations) EXPECT_EQ(o.pixel, track.observations[static_cast<size_t>(o.frame)].pixel);
  FeatureTrack two = track;
  two.observations.erase(two.observations.begin());
  point.observations.erase(point.observations.begin());
  EXPECT_TRUE(refine(none_fit, 0.5, two).observations.empty());
}

// When the reference view (nearest the mean viewing direction) fits none
// of the others (here its image is flat: blurred out, say), the track is
// lost with one reference; with two, the next view nearest the mean
// direction is the reference, and the track is kept if three views are
// left. Each view's SIFT pixel is 0.3 px off its projection, so each fitted
// view, which sees the surface point of the reference's pixel, is too.
TEST(TrackRefinement, ATrackWhoseReferenceFitsNothingTriesTheNextView) {
  const CameraModel camera = testing::PinholeCamera(64, 64, 100, 31.5, 31.5);
  const double depth = 2.0, step = 0.02;
  const std::vector<Blob> texture = Blurred(MakeTexture(3, 12, 40), 0.7);
  const Eigen::Vector3d truth((31.3 - 31.5) * depth / 100 + step, (32.6 - 31.5) * depth / 100, depth);
  const PoseMap poses = CamerasAlongX(4, step);
  Eigen::Vector3d mean_direction = Eigen::Vector3d::Zero();
  for (const auto& [frame, pose] : poses) mean_direction += (pose.Center() - truth).normalized();
  // The first reference: the view nearest the mean viewing direction.
  FrameId first = 0;
  for (FrameId k = 1; k < 4; ++k) {
    if ((poses.at(k).Center() - truth).normalized().dot(mean_direction) >
        (poses.at(first).Center() - truth).normalized().dot(mean_direction)) {
      first = k;
    }
  }
  std::map<FrameId, cv::Mat> images;
  for (FrameId k = 0; k < 4; ++k) {
    const double t = step * static_cast<double>(k);
    images[k] = k == first ? Render({}, 64, Eigen::Matrix2d::Identity(), {0, 0}, 1, 0, 1, 41)
                           : Render(texture, 64, Eigen::Matrix2d::Identity(), {-31.5 + 100 * t / depth, -31.5}, 1, 0, 1, 40 + k);
  }
  const KeyframeImageLookup image_of = FullSizeOnly(images);
  const TrackAndPoint sift = SiftTrack(8, truth, poses, camera, [](FrameId) { return Eigen::Vector2d(0.3, 0); });
  PatchRefinementOptions one_reference;
  one_reference.reference_attempts = 1;
  EXPECT_TRUE(RefineTrackViews(sift.track, sift.point, poses, image_of, camera, one_reference).observations.empty());
  const PatchRefinementOptions two_references;  // the default
  ASSERT_EQ(two_references.reference_attempts, 2);
  const FeatureTrack refined = RefineTrackViews(sift.track, sift.point, poses, image_of, camera, two_references);
  ASSERT_EQ(refined.observations.size(), 3u);
  for (const TrackObservation& o : refined.observations) {
    EXPECT_NE(o.frame, first);
    const Eigen::Vector2d off = o.pixel - camera.Project(poses.at(o.frame) * truth);
    EXPECT_LT((off - Eigen::Vector2d(0.3, 0)).norm(), 0.1) << "frame " << o.frame;
  }
  // Without the textured view farthest from the flat one (which stays the
  // first reference), the two left fit only each other: not kept.
  TrackAndPoint three = sift;
  const FrameId dropped = first <= 1 ? 3 : 0;
  three.track.observations.erase(three.track.observations.begin() + static_cast<std::ptrdiff_t>(dropped));
  three.point.observations.erase(three.point.observations.begin() + static_cast<std::ptrdiff_t>(dropped));
  EXPECT_TRUE(RefineTrackViews(three.track, three.point, poses, image_of, camera, two_references).observations.empty());
}

// Three cameras side by side over a plane with one straight edge on it,
// 1 px apart in the image: the epipolar lines run along x. The free fits
// slide along the edge and are refused, so the track is lost; with the
// lines' error given, each view is fitted along its line to where the
// edge crosses it, the truth's projection, and counted as a line fit.
TEST(TrackRefinement, AnEdgeIsFittedAlongTheEpipolarLines) {
  const CameraModel camera = testing::PinholeCamera(64, 64, 100, 31.5, 31.5);
  const double depth = 2.0, step = 0.02;
  const PoseMap poses = CamerasAlongX(3, step);
  const Eigen::Vector3d truth(-0.004 + step, 0.022, depth);
  for (const double normal_deg : {20.0, 45.0, 110.0}) {
    std::map<FrameId, cv::Mat> images;
    for (FrameId k = 0; k < 3; ++k) {
      images[k] = RenderEdge(64, camera.Project(poses.at(k) * truth), normal_deg, 1.0, 2, 50 + static_cast<unsigned>(k));
    }
    const KeyframeImageLookup image_of = FullSizeOnly(images);
    const TrackAndPoint sift = SiftTrack(5, truth, poses, camera, [](FrameId k) { return Eigen::Vector2d(k == 1 ? 0 : 0.4, 0); });
    TrackRefinementReport free_only;
    EXPECT_TRUE(RefineTrackViews(sift.track, sift.point, poses, image_of, camera, {}, 0.0, 0.0, &free_only).observations.empty());
    EXPECT_EQ(free_only.line_fits, 0);
    TrackRefinementReport report;
    const FeatureTrack refined = RefineTrackViews(sift.track, sift.point, poses, image_of, camera, {}, 0.0, 0.02, &report);
    ASSERT_EQ(refined.observations.size(), 3u) << normal_deg;
    EXPECT_EQ(report.line_fits, 2);
    for (const TrackObservation& o : refined.observations) {
      EXPECT_LT((o.pixel - camera.Project(poses.at(o.frame) * truth)).norm(), 0.05) << normal_deg << " frame " << o.frame;
      if (o.frame != 1) {
        EXPECT_LT(o.sigma_px, 0.1);
      }
    }
  }
}

// The edge scene with the middle view (the first reference) flat: the
// second reference, an end view, fits the other end along its line but
// not the flat one, so its two views are discarded, and the line fit
// that was made for them is not counted.
TEST(TrackRefinement, ADiscardedReferenceAttemptsLineFitsAreNotCounted) {
  const CameraModel camera = testing::PinholeCamera(64, 64, 100, 31.5, 31.5);
  const double depth = 2.0, step = 0.02;
  const PoseMap poses = CamerasAlongX(3, step);
  const Eigen::Vector3d truth(-0.004 + step, 0.022, depth);
  std::map<FrameId, cv::Mat> images;
  for (FrameId k = 0; k < 3; ++k) {
    images[k] = k == 1 ? Render({}, 64, Eigen::Matrix2d::Identity(), {0, 0}, 1, 0, 1, 61)
                       : RenderEdge(64, camera.Project(poses.at(k) * truth), 45.0, 1.0, 2, 60 + static_cast<unsigned>(k));
  }
  const KeyframeImageLookup image_of = FullSizeOnly(images);
  const TrackAndPoint sift = SiftTrack(5, truth, poses, camera, [](FrameId k) { return Eigen::Vector2d(k == 1 ? 0 : 0.4, 0); });
  // With the middle view an edge like the others, the middle reference
  // fits the ends, along the line where the free fit slides, and counts it.
  std::map<FrameId, cv::Mat> textured = images;
  textured[1] = RenderEdge(64, camera.Project(poses.at(1) * truth), 45.0, 1.0, 2, 62);
  const KeyframeImageLookup textured_of = FullSizeOnly(textured);
  TrackRefinementReport kept;
  ASSERT_EQ(RefineTrackViews(sift.track, sift.point, poses, textured_of, camera, {}, 0.0, 0.02, &kept).observations.size(), 3u);
  EXPECT_GE(kept.line_fits, 1);
  TrackRefinementReport discarded;
  EXPECT_TRUE(RefineTrackViews(sift.track, sift.point, poses, image_of, camera, {}, 0.0, 0.02, &discarded).observations.empty());
  EXPECT_EQ(discarded.line_fits, 0);
}

// A walk that comes closer and backs off: one camera sees the textured
// plane from half the reference distance (the patch twice as large), one
// from twice it (half as large), beside a camera at the same distance.
// With balance_scale the fits run on the halved images that see the patch
// at the reference's scale, and every view comes back, in full-image
// pixels, to the surface point at the reference's pixel.
TEST(TrackRefinement, ViewsCloserOrFartherAreFittedAtTheReferencesScale) {
  const CameraModel camera = testing::PinholeCamera(64, 64, 100, 31.5, 31.5);
  // Texture units of 2 cm: one unit per pixel at 2 m. Blobs of 2 units are
  // 4 px in the close view and 1 px in the far one.
  const std::vector<Blob> texture = Blurred(MakeTexture(2, 17, 70), 0.5);
  const std::vector<Eigen::Vector3d> centres{{0, 0, 0}, {0.02, 0, 0}, {0, 0, 1}, {0, 0, -2}};
  std::map<FrameId, std::vector<cv::Mat>> pyramids;
  PoseMap poses;
  for (FrameId k = 0; k < 4; ++k) {
    const Eigen::Vector3d c = centres[static_cast<size_t>(k)];
    poses[k] = Rigid3d(Eigen::Quaterniond::Identity(), -c);
    const double distance = 2 - c.z();
    // Pixel x sees the plane at (x - 31.5) distance / 100 + c metres.
    const Eigen::Vector2d shift = Eigen::Vector2d(-31.5, -31.5) * 0.5 * distance + 50 * c.head<2>();
    pyramids[k].push_back(Render(texture, 64, 0.5 * distance * Eigen::Matrix2d::Identity(), shift, 1, 0, 1, 40 + k));
    for (int level = 1; level <= 3; ++level) {
      pyramids[k].emplace_back();
      cv::pyrDown(pyramids[k][static_cast<size_t>(level - 1)], pyramids[k].back());
    }
  }
  const Eigen::Vector3d truth(-0.004, 0.022, 2.0);
  const TrackAndPoint sift = SiftTrack(3, truth, poses, camera, [](FrameId) { return Eigen::Vector2d(0.3, 0); });
  const FeatureTrack& track = sift.track;
  const FeaturePoint& point = sift.point;
  const KeyframeImageLookup image_of = [&](FrameId frame, int level) -> const cv::Mat* {
    const std::vector<cv::Mat>& levels = pyramids.at(frame);
    return level < static_cast<int>(levels.size()) ? &levels[static_cast<size_t>(level)] : nullptr;
  };
  // How far each fitted view lies from the surface point at the reference's
  // pixel (the reference keeps its pixel and has no sigma); -1: refused.
  const auto errors = [&]() {
    PatchRefinementOptions options;
    options.balance_scale = true;  // the default
    const FeatureTrack refined = RefineTrackViews(track, point, poses, image_of, camera, options);
    std::map<FrameId, double> error{{0, -1}, {1, -1}, {2, -1}, {3, -1}};
    const auto reference = std::find_if(refined.observations.begin(), refined.observations.end(),
                                        [](const TrackObservation& o) { return o.sigma_px == 0; });
    if (reference == refined.observations.end()) return error;
    const Eigen::Vector3d ray = camera.PixelToNormalized(reference->pixel).homogeneous();
    const Rigid3d& ref_pose = poses.at(reference->frame);
    const Eigen::Vector3d centre = ref_pose.Center();
    const Eigen::Vector3d seen = centre + ray * ((2.0 - centre.z()) / ray.z());
    for (const TrackObservation& o : refined.observations) {
      if (&o != &*reference) error[o.frame] = (o.pixel - camera.Project(poses.at(o.frame) * seen)).norm();
    }
    return error;
  };
  // Measured 0.007-0.04 px (without balancing the far view is refused): a
  // fit on a halved image is located to twice a full image's 0.05 px.
  int fitted = 0;
  for (const auto& [frame, error] : errors()) {
    if (error < 0) continue;
    ++fitted;
    EXPECT_LT(error, 0.1) << "frame " << frame;
  }
  EXPECT_EQ(fitted, 3);
}

// A textured plane (a smoothed noise image, `texture_mm` per texel) seen by
// a pinhole camera: each pixel averages 4 x 4 rays intersected with the
// plane (through `origin`, in-plane unit axes u and w), with Gaussian noise.
cv::Mat RenderPlane(const cv::Mat& texture, double texture_mm, const Eigen::Vector3d& origin, const Eigen::Vector3d& u,
                    const Eigen::Vector3d& w, const Rigid3d& cam_from_world, const CameraModel& camera, double noise,
                    unsigned seed) {
  const Eigen::Vector3d normal = u.cross(w), centre = cam_from_world.Center();
  const Eigen::Quaterniond world_from_cam = cam_from_world.rotation.conjugate();
  cv::Mat image(camera.height, camera.width, CV_64F);
  for (int y = 0; y < camera.height; ++y) {
    for (int x = 0; x < camera.width; ++x) {
      double sum = 0;
      for (int sy = 0; sy < 4; ++sy) {
        for (int sx = 0; sx < 4; ++sx) {
          const Eigen::Vector2d pixel(x - 0.375 + 0.25 * sx, y - 0.375 + 0.25 * sy);
          const Eigen::Vector3d ray = world_from_cam * camera.PixelToNormalized(pixel).homogeneous();
          const Eigen::Vector3d hit = centre + ray * (normal.dot(origin - centre) / normal.dot(ray));
          const double tx = (hit - origin).dot(u) * 1000 / texture_mm + texture.cols / 2.0;
          const double ty = (hit - origin).dot(w) * 1000 / texture_mm + texture.rows / 2.0;
          cv::Mat texel;
          cv::getRectSubPix(texture, {1, 1}, {static_cast<float>(tx), static_cast<float>(ty)}, texel, CV_32F);
          sum += texel.at<float>(0, 0);
        }
      }
      image.at<double>(y, x) = sum / 16;
    }
  }
  return WithNoise(image, noise, seed);
}

// Two cameras 2 m from a point, their rays 30 degrees apart, over a plane
// through it turned 25-60 degrees towards the reference (in the plane of
// the two rays) from the plane facing them: the other view sees the
// surface 1.2-3x more foreshortened. Textures (blur 0.9-1.6 px), noise
// (1-2.5 grey) and SIFT's errors (0.3 px) as on real frames. From the
// facing plane's warp the fits at 50 degrees and more run off (11 of 24
// cases accepted, measured); from planes tilted 30 or 60 degrees, the
// retries' starts, 4 more are accepted. Every accepted fit lies within
// 0.1 px (the fits' limit on their sigma) of where the reference pixel's
// surface point is in the view (measured: 0.08 px at worst). Turned the
// other way, the reference is the more foreshortened view and the fits,
// with or without retries, are off by 0.1-0.25 px (docs/features.md).
TEST(TrackRefinement, AnObliqueSurfaceIsFittedFromATiltedPlane) {
  const CameraModel camera = testing::PinholeCamera(64, 64, 800, 31.5, 31.5);
  const Eigen::Vector3d truth(0, 0, 2);
  PoseMap poses;
  for (FrameId k = 0; k < 2; ++k) {
    const double phi = (k == 0 ? -15.0 : 15.0) * M_PI / 180;  // the camera's angle round the point
    const Eigen::Vector3d centre = truth + 2 * Eigen::Vector3d(std::sin(phi), 0, -std::cos(phi));
    const Eigen::Quaterniond cam_from_world(Eigen::AngleAxisd(phi, Eigen::Vector3d::UnitY()));  // looks at the point
    poses[k] = Rigid3d(cam_from_world, -(cam_from_world * centre));
  }
  ASSERT_LT((camera.Project(poses.at(0) * truth) - Eigen::Vector2d(31.5, 31.5)).norm(), 1e-9);
  PatchRefinementOptions no_retries;
  no_retries.tilt_retries = 0;
  const PatchRefinementOptions retries;  // the default
  ASSERT_EQ(retries.tilt_retries, 2);
  int accepted_without = 0, accepted_with = 0, cases = 0, tilted_fits = 0;
  double worst_error = 0;
  for (const double tilt_deg : {25.0, 35.0, 45.0, 50.0, 55.0, 60.0}) {
    for (unsigned seed = 1; seed <= 4; ++seed) {
      const double texel_blur = 0.8 + 0.3 * seed, noise = 0.5 + 0.5 * seed;
      cv::Mat texture(400, 400, CV_32F);
      cv::setRNGSeed(static_cast<int>(seed));
      cv::randn(texture, 0, 60);
      cv::GaussianBlur(texture, texture, {0, 0}, texel_blur);
      texture += 128;
      const Eigen::Vector3d normal =
          Eigen::AngleAxisd(tilt_deg * M_PI / 180, Eigen::Vector3d::UnitY()) * Eigen::Vector3d(0, 0, -1);
      const Eigen::Vector3d u = Eigen::Vector3d::UnitY().cross(normal).normalized(), w = Eigen::Vector3d::UnitY();
      std::map<FrameId, cv::Mat> images;
      for (FrameId k = 0; k < 2; ++k) images[k] = RenderPlane(texture, 2.0, truth, u, w, poses.at(k), camera, noise, 50 + seed + k);
      const TrackAndPoint sift = SiftTrack(9, truth, poses, camera, [](FrameId k) { return Eigen::Vector2d(0.3, k == 0 ? -0.2 : 0.2); });
      const KeyframeImageLookup image_of = FullSizeOnly(images);
      ++cases;
      for (const bool with : {false, true}) {
        TrackRefinementReport report;
        const FeatureTrack refined =
            RefineTrackViews(sift.track, sift.point, poses, image_of, camera, with ? retries : no_retries, 0.0, 0.0, &report);
        tilted_fits += report.tilted_fits;
        if (refined.observations.size() != 2) continue;
        (with ? accepted_with : accepted_without)++;
        const TrackObservation& reference = refined.observations[0].sigma_px == 0 ? refined.observations[0] : refined.observations[1];
        const TrackObservation& fitted = &reference == &refined.observations[0] ? refined.observations[1] : refined.observations[0];
        // The surface point the reference's pixel sees, in the fitted view.
        const Rigid3d& ref_pose = poses.at(reference.frame);
        const Eigen::Vector3d ray = ref_pose.rotation.conjugate() * camera.PixelToNormalized(reference.pixel).homogeneous();
        const Eigen::Vector3d seen = ref_pose.Center() + ray * (normal.dot(truth - ref_pose.Center()) / normal.dot(ray));
        const double error = (fitted.pixel - camera.Project(poses.at(fitted.frame) * seen)).norm();
        worst_error = std::max(worst_error, error);
      }
    }
  }
  std::cout << "accepted from the facing plane " << accepted_without << ", with retries " << accepted_with << " of " << cases
            << "; worst error " << worst_error << " px\n";
  EXPECT_GE(accepted_with, accepted_without + 3);
  EXPECT_EQ(tilted_fits, accepted_with - accepted_without);  // counted in report.json's feature_triangulation
  EXPECT_LT(worst_error, 0.1);
}

}  // namespace
}  // namespace tagsfm

