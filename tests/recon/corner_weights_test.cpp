// Each corner weighted by the detector's covariance of it (corner_weights.h):
// the weight whitens that covariance, through the lens too, and in an
// adjustment noisy corners that say so count less.
#include <cmath>
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
  synth::SyntheticSceneOptions options;
  options.frames = 20;
  options.noise_px = 0.0;
  const synth::SyntheticScene scene = synth::MakeSyntheticBoxScene(options);
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
  TargetConfig targets;
  targets.size_m = options.tag_size_m;
  auto quiet_rms = [&](bool weighted) {
    ReconstructorOptions recon_options;
    recon_options.weight_corners = weighted;
    auto recon = Reconstructor::Create(scene.camera, targets, std::nullopt, recon_options);
    EXPECT_TRUE(recon.has_value());
    if (!recon) return 1.0;
    for (const auto& d : detections) (*recon)->AddFrame(d);
    const ReconstructionResult result = (*recon)->Finish();
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

}  // namespace
}  // namespace tagsfm
