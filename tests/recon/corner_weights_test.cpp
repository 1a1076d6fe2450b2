// Each corner weighted by the detector's covariance of it (corner_weights.h):
// the weight whitens that covariance, through the lens too, and in an
// adjustment noisy corners that say so count less.
#include <algorithm>
#include <cmath>
#include <map>
#include <set>
#include <utility>
#include <vector>
#include <random>

#include <Eigen/Dense>
#include <gtest/gtest.h>

#include "tagsfm/eval/truth_comparison.h"
#include "tagsfm/recon/corner_weights.h"
#include "tagsfm/recon/reconstructor.h"
#include "tagsfm/synth/box_scene.h"
#include "test_camera.h"

namespace tagsfm {
namespace {

Eigen::Matrix2d Rotated(double angle, double sigma_a, double sigma_b) {
  const Eigen::Matrix2d r = Eigen::Rotation2Dd(angle).toRotationMatrix();
  return r * Eigen::Vector2d(sigma_a * sigma_a, sigma_b * sigma_b).asDiagonal() * r.transpose();
}

// The exact corners of a 20-frame box walk, for the tests to add their noise to.
synth::SyntheticScene ExactBoxScene() {
  synth::SyntheticSceneOptions options;
  options.frames = 20;
  options.noise_px = 0.0;
  return synth::MakeSyntheticBoxScene(options);
}

ReconstructionResult Reconstruct(const synth::SyntheticScene& scene, const std::vector<DetectionSet>& detections,
                                 bool weighted) {
  TargetConfig targets;
  targets.size_m = synth::SyntheticSceneOptions{}.tag_size_m;
  ReconstructorOptions recon_options;
  recon_options.weight_corners = weighted;
  auto recon = Reconstructor::Create(scene.camera, targets, std::nullopt, recon_options);
  EXPECT_TRUE(recon.has_value());
  if (!recon) return {};
  for (const auto& d : detections) (*recon)->AddFrame(d);
  return (*recon)->Finish();
}

TEST(CornerWeights, WeightWhitensTheCovarianceAtTheReference) {
  const double reference = 0.03;
  const Eigen::Matrix2d c = Rotated(0.6, 0.05, 0.02);
  const Eigen::Matrix2d w = CornerWeight(c, reference);
  // W C W^T = ref^2 I: the weighted residual of a corner has the reference's spread.
  EXPECT_TRUE((w * c * w.transpose()).isApprox(reference * reference * Eigen::Matrix2d::Identity(), 1e-9));
  // Unknown (zero, or not positive definite): as unweighted.
  EXPECT_TRUE(CornerWeight(Eigen::Matrix2d::Zero(), reference).isIdentity());
  EXPECT_TRUE(CornerWeight(Rotated(0.2, 0.05, 0.0), reference).isIdentity());
  // Held within 5x of the reference sigma: a 1e-4 px corner weighs as one of 0.006.
  const Eigen::Matrix2d tiny = CornerWeight(1e-8 * Eigen::Matrix2d::Identity(), reference);
  EXPECT_NEAR(tiny(0, 0), 5.0, 1e-9);
  const Eigen::Matrix2d huge = CornerWeight(Eigen::Matrix2d::Identity(), reference);
  EXPECT_NEAR(huge(1, 1), 0.2, 1e-9);
}

TEST(CornerWeights, UndistortedWeightCarriesTheCovarianceThroughTheLens) {
  CameraModel camera = testing::PinholeCamera(1280, 720, 900.0, 640.2, 359.1);
  camera.fy = 905;
  camera.distortion = {-0.3, 0.1, 0.0, 0.0, 0.0};
  TagObservation obs;
  obs.pixels = {Eigen::Vector2d(1180, 650), Eigen::Vector2d(1220, 652), Eigen::Vector2d(1221, 690),
                Eigen::Vector2d(1182, 688)};  // near the image's corner, where the lens stretches most
  const std::array<Eigen::Matrix2d, 4> covariance = {Rotated(0.1, 0.04, 0.02), Rotated(0.9, 0.03, 0.03),
                                                     Rotated(2.0, 0.06, 0.01), Rotated(-0.4, 0.02, 0.05)};
  const double reference = 0.03;
  SetCornerWeights(covariance, camera, reference, 0.0, &obs);
  for (int k = 0; k < 4; ++k) {
    // The undistortion's Jacobian to undistorted pixels (fx, fy times
    // normalized), here with a step ten times finer than the weights'.
    Eigen::Matrix2d j;
    for (int axis = 0; axis < 2; ++axis) {
      const Eigen::Vector2d d = 0.05 * Eigen::Vector2d::Unit(axis);
      j.col(axis) = Eigen::Vector2d(camera.fx, camera.fy)
                        .cwiseProduct(camera.PixelToNormalized(obs.pixels[k] + d) - camera.PixelToNormalized(obs.pixels[k] - d)) /
                    0.1;
    }
    // The lens stretches this far out: the weights in the two spaces differ.
    EXPECT_GT((j - Eigen::Matrix2d::Identity()).norm(), 0.1);
    const Eigen::Matrix2d undistorted = j * covariance[k] * j.transpose();
    const Eigen::Matrix2d whitened = obs.weight_undistorted[k] * undistorted * obs.weight_undistorted[k].transpose();
    EXPECT_TRUE(whitened.isApprox(reference * reference * Eigen::Matrix2d::Identity(), 1e-3)) << whitened;
    const Eigen::Matrix2d in_pixels = obs.weight_pixels[k] * covariance[k] * obs.weight_pixels[k].transpose();
    EXPECT_TRUE(in_pixels.isApprox(reference * reference * Eigen::Matrix2d::Identity(), 1e-9)) << in_pixels;
  }
}

// The box scene's exact corners, every third tag's with 0.3 px of noise
// and the rest's 0.03 px, each with that covariance: weighted, the noisy
// tags no longer pull the frames' poses and the quiet tags' positions.
TEST(CornerWeights, NoisyCornersThatSaySoCountLess) {
  const synth::SyntheticScene scene = ExactBoxScene();
  std::vector<DetectionSet> detections = scene.detections;
  std::mt19937 rng(7);
  std::normal_distribution<double> unit(0.0, 1.0);
  for (DetectionSet& set : detections) {
    for (TagDetection& tag : set.tags) {
      const double sigma = tag.id % 3 == 0 ? 0.3 : 0.03;
      for (int k = 0; k < 4; ++k) {
        tag.corners[k] += sigma * Eigen::Vector2d(unit(rng), unit(rng));
        tag.corner_covariance[k] = sigma * sigma * Eigen::Matrix2d::Identity();
      }
    }
  }
  auto quiet_rms = [&](bool weighted) {
    const ReconstructionResult result = Reconstruct(scene, detections, weighted);
    // The quiet tags only: both runs must place them, the noisy ones differ by design.
    TargetCornerMap quiet_truth, quiet;
    for (const auto& [id, corners] : result.Targets()) {
      if (id % 3 != 0 && scene.targets.count(id)) {
        quiet.emplace(id, corners);
        quiet_truth.emplace(id, scene.targets.at(id));
      }
    }
    EXPECT_GT(quiet.size(), 15u);
    const eval::TruthComparison c = eval::CompareWithTruth({}, quiet, {}, quiet_truth, true);
    return c.corner_rms_m;
  };
  const double unweighted = quiet_rms(false), weighted = quiet_rms(true);
  std::printf("quiet tags' corner RMS: unweighted %.1f um, weighted %.1f um\n", 1e6 * unweighted, 1e6 * weighted);
  EXPECT_LT(weighted, 0.6 * unweighted);
}

// A tag that moved half way through the walk, its corners ten times more
// precise than the others' (weighted at the cap: 100x per squared error).
// The decisions (which tags are mapped, which views are outliers) are taken
// on equal votes, weighted or not; the weights change only the final
// adjustment's values. On the real swatbotics room, weights in the live
// window mapped a doubtful tag whose heavy views then outvoted three others
// (docs/recon.md).
TEST(CornerWeights, WeightsChangeTheValuesNotTheDecisions) {
  const synth::SyntheticScene scene = ExactBoxScene();
  std::vector<DetectionSet> detections = scene.detections;
  std::map<TagId, int> views;
  for (const DetectionSet& set : detections) {
    for (const TagDetection& tag : set.tags) ++views[tag.id];
  }
  // The tag seen in most frames moves 3.6 cm after the tenth frame.
  TagId moved = views.begin()->first;
  for (const auto& [id, n] : views) moved = n > views[moved] ? id : moved;
  std::mt19937 rng(11);
  std::normal_distribution<double> unit(0.0, 1.0);
  int moved_views_after = 0;
  for (size_t f = 0; f < detections.size(); ++f) {
    for (TagDetection& tag : detections[f].tags) {
      const bool heavy = tag.id == moved;
      const double sigma = heavy ? 0.006 : 0.06;
      for (int k = 0; k < 4; ++k) {
        if (heavy && f >= 10) {
          const Eigen::Vector3d shifted = scene.targets.at(moved)[k] + Eigen::Vector3d(0.03, 0.0, -0.02);
          tag.corners[k] = scene.camera.Project(scene.cam_from_world[f] * shifted);
        }
        tag.corners[k] += sigma * Eigen::Vector2d(unit(rng), unit(rng));
        tag.corner_covariance[k] = sigma * sigma * Eigen::Matrix2d::Identity();
      }
      moved_views_after += heavy && f >= 10;
    }
  }
  ASSERT_GE(moved_views_after, 3);
  const ReconstructionResult unweighted = Reconstruct(scene, detections, false),
                             weighted = Reconstruct(scene, detections, true);
  // Which views each run used: "frame/tag" for every view of a mapped tag kept.
  auto used = [](const ReconstructionResult& result) {
    std::set<std::pair<FrameId, TagId>> kept;
    for (const FrameState& frame : result.frames) {
      for (const TagObservation& obs : frame.tags) {
        if (frame.registered && result.tags.count(obs.id) && !obs.outlier) kept.insert({frame.frame, obs.id});
      }
    }
    return kept;
  };
  const auto kept_unweighted = used(unweighted), kept_weighted = used(weighted);
  EXPECT_EQ(kept_unweighted, kept_weighted);
  int moved_kept = 0;
  for (const auto& [frame, id] : kept_weighted) moved_kept += id == moved;
  // The moved tag keeps one of its halves at most.
  EXPECT_LE(moved_kept, std::max(views[moved] - moved_views_after, moved_views_after));
  auto others_rms = [&](const ReconstructionResult& result) {
    TargetCornerMap truth, mapped;
    for (const auto& [id, corners] : result.Targets()) {
      if (id != moved && scene.targets.count(id)) {
        mapped.emplace(id, corners);
        truth.emplace(id, scene.targets.at(id));
      }
    }
    return eval::CompareWithTruth({}, mapped, {}, truth, true).corner_rms_m;
  };
  std::printf("moved tag %d: %d of its %d views kept (%d after the move); views kept: %zu unweighted, %zu weighted; "
              "the other tags' corner RMS %.1f um unweighted, %.1f um weighted\n",
              moved, moved_kept, views[moved], moved_views_after, kept_unweighted.size(), kept_weighted.size(),
              1e6 * others_rms(unweighted), 1e6 * others_rms(weighted));
  // The same views, the heavy tag's now weighing 100x: the others' corners
  // no worse than unweighted (by a tenth: one draw of noise).
  EXPECT_LT(others_rms(weighted), 1.1 * others_rms(unweighted));
}

// The fit itself, on drawn residuals: 3,200 corners whose predicted sigma
// spreads 0.01-0.1 px and whose 2D errors have variance scale^2 sigma^2 +
// floor^2 per axis. Each of 16 bins' medians is good to ~7 %: the noise the
// model predicts for a typical (0.03 px) and a poor (0.1 px) corner comes
// out within 10 %, the floor within 0.015 px (its square is the line's
// intercept, ~1e-4 px^2 uncertain here).
TEST(CornerWeights, TheNoiseFitFindsTheScaleAndTheFloor) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> sigma(0.01, 0.1);
  std::normal_distribution<double> unit(0.0, 1.0);
  for (const auto& [scale, floor] : std::vector<std::pair<double, double>>{{1.0, 0.0}, {2.0, 0.02}, {0.5, 0.1}}) {
    std::vector<std::pair<double, double>> corners;
    for (int i = 0; i < 3200; ++i) {
      const double s = sigma(rng), total = std::hypot(scale * s, floor);
      const Eigen::Vector2d e = total * Eigen::Vector2d(unit(rng), unit(rng));
      corners.emplace_back(s * s, e.squaredNorm());
    }
    const CornerNoiseModel model = FitCornerNoise(corners, 1.0);
    std::printf("scale %.1f floor %.2f px: fitted %.3f, %.4f px\n", scale, floor, model.scale, model.floor_px);
    for (const double s : {0.03, 0.1}) {
      const double truth = std::hypot(scale * s, floor);
      EXPECT_NEAR(std::hypot(model.scale * s, model.floor_px), truth, 0.1 * truth) << scale << " " << floor << " " << s;
    }
    EXPECT_NEAR(model.floor_px, floor, 0.015) << scale << " " << floor;
    // Residuals shrunk by the adjustment's redundancy are scaled back up.
    for (auto& c : corners) c.second *= 0.8;
    EXPECT_NEAR(FitCornerNoise(corners, 0.8).scale, model.scale, 1e-9);
  }
  // Too few corners to say: the covariance as it is.
  const CornerNoiseModel few = FitCornerNoise({{0.01, 1.0}, {0.02, 2.0}}, 1.0);
  EXPECT_EQ(few.scale, 1.0);
  EXPECT_EQ(few.floor_px, 0.0);
}

// The corners' errors against what the detector says, as scale^2 C +
// floor^2, measured from the residuals: an honest covariance gives scale 1
// and no floor, an optimistic edge fit a scale, a lens or a print the model
// does not know a floor, and errors that do not follow C at all a floor with
// scale ~0 (the corners then count the same).
TEST(CornerWeights, TheCornersNoiseAgainstTheirCovarianceIsMeasured) {
  const synth::SyntheticScene scene = ExactBoxScene();
  // Each tag says sigma 0.02, 0.04 or 0.08 px (by its id); its corners get
  // noise of sqrt((scale sigma)^2 + floor^2).
  auto measured = [&](double scale, double floor) {
    std::vector<DetectionSet> detections = scene.detections;
    std::mt19937 rng(5);
    std::normal_distribution<double> unit(0.0, 1.0);
    for (DetectionSet& set : detections) {
      for (TagDetection& tag : set.tags) {
        const double said = 0.02 * (1 << (tag.id % 3));
        const double noise = std::hypot(scale * said, floor);
        for (int k = 0; k < 4; ++k) {
          tag.corners[k] += noise * Eigen::Vector2d(unit(rng), unit(rng));
          tag.corner_covariance[k] = said * said * Eigen::Matrix2d::Identity();
        }
      }
    }
    const CornerNoiseModel model = Reconstruct(scene, detections, true).corner_noise;
    std::printf("scale %.2f floor %.3f px: measured scale %.3f floor %.4f px\n", scale, floor, model.scale,
                model.floor_px);
    return model;
  };
  // ~1,400 corners in 14 bins of ~100: each bin's variance is good to ~15 %.
  // The adjustment that the residuals come from is unweighted, so the noisy
  // corners' errors reach the precise ones' residuals and the scale comes
  // out ~10 % high. What the weights use is the floor in the covariance's
  // units (floor / scale): ~0 for an honest or optimistic covariance (the
  // weights keep their ratios), several times the largest sigma where the
  // errors do not follow C (the weights then within 2x of each other).
  const CornerNoiseModel honest = measured(1.0, 0.0);
  EXPECT_NEAR(honest.scale, 1.0, 0.15);
  EXPECT_LT(honest.floor_px / honest.scale, 0.01);
  const CornerNoiseModel optimistic = measured(2.0, 0.0);
  EXPECT_NEAR(optimistic.scale, 2.0, 0.3);
  EXPECT_LT(optimistic.floor_px / optimistic.scale, 0.01);
  const CornerNoiseModel lens = measured(1.0, 0.1);
  EXPECT_NEAR(lens.floor_px, 0.1, 0.015);
  EXPECT_NEAR(lens.floor_px / lens.scale, 0.1, 0.03);
  const CornerNoiseModel unrelated = measured(0.0, 0.3);
  EXPECT_NEAR(unrelated.floor_px, 0.3, 0.03);
  EXPECT_GT(unrelated.floor_px / unrelated.scale, 0.08 * 1.5);
}

}  // namespace
}  // namespace tagsfm
