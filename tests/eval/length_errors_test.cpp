// The length-error report and the map's precision against maps whose errors
// are known: a pure scale error, and tag centres moved by Gaussian noise of
// the sigma the covariance states (error/sigma then has mean ~0, std ~1).
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "tagsfm/eval/evaluation.h"
#include "tagsfm/recon/tag_geometry.h"

namespace tagsfm::eval {
namespace {

// 30 tags of 6 cm on a 2 m x 1 m x 0.8 m box's surfaces, facing +z.
TargetCornerMap BoxTargets() {
  TargetCornerMap targets;
  for (int id = 0; id < 30; ++id) {
    const Eigen::Vector3d centre(0.07 * id, 0.35 * (id % 4), 0.25 * (id % 3));
    const double h = 0.03;
    targets[id] = {centre + Eigen::Vector3d(-h, -h, 0), centre + Eigen::Vector3d(h, -h, 0),
                   centre + Eigen::Vector3d(h, h, 0), centre + Eigen::Vector3d(-h, h, 0)};
  }
  return targets;
}

TargetCornerMap Transformed(const TargetCornerMap& targets, double scale, const Eigen::Quaterniond& rotation,
                            const Eigen::Vector3d& translation) {
  TargetCornerMap out;
  for (const auto& [id, corners] : targets) {
    for (size_t c = 0; c < 4; ++c) out[id][c] = rotation * (scale * corners[c]) + translation;
  }
  return out;
}

TEST(LengthErrors, ScaleErrorIsTheSlopeOfErrorAgainstLength) {
  const TargetCornerMap truth = BoxTargets();
  // 300 ppm too large, and in another frame: lengths need no alignment.
  const Eigen::Quaterniond rotation(Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()));
  const TargetCornerMap estimate = Transformed(truth, 1.0003, rotation, Eigen::Vector3d(0.4, -2, 1));
  const LengthErrors lengths = CompareLengths(truth, estimate, std::nullopt);
  ASSERT_EQ(lengths.pairs.size(), 30u * 29u / 2u);
  EXPECT_NEAR(lengths.error_per_length_ppm, 300.0, 1e-6);
  for (const LengthError& p : lengths.pairs) {
    EXPECT_NEAR(p.error_m, 3e-4 * p.true_length_m, 1e-12);
    EXPECT_FALSE(p.sigma_m.has_value());
  }
  EXPECT_LE(lengths.pairs.front().true_length_m, lengths.pairs.back().true_length_m);  // shortest first
  EXPECT_EQ(lengths.normalized_count, 0);
}

TEST(LengthErrors, ErrorOverSigmaIsStandardNormalWhenTheCovarianceIsRight) {
  const TargetCornerMap truth = BoxTargets();
  const double sigma = 0.0002;  // per tag centre and axis
  TagCovariance covariance;
  for (const auto& [id, corners] : truth) covariance.ids.push_back(id);
  const int n = 6 * static_cast<int>(covariance.ids.size());
  covariance.covariance = Eigen::MatrixXd::Zero(n, n);
  for (int i = 0; i < n; i += 6) covariance.covariance.block<3, 3>(i + 3, i + 3) = sigma * sigma * Eigen::Matrix3d::Identity();
  std::mt19937 rng(14);
  std::normal_distribution<double> noise(0.0, sigma);
  TargetCornerMap estimate;
  for (const auto& [id, corners] : truth) {
    const Eigen::Vector3d shift(noise(rng), noise(rng), noise(rng));
    for (size_t c = 0; c < 4; ++c) estimate[id][c] = corners[c] + shift;
  }
  const LengthErrors lengths = CompareLengths(truth, estimate, covariance);
  ASSERT_EQ(lengths.normalized_count, 435);
  for (const LengthError& p : lengths.pairs) EXPECT_NEAR(*p.sigma_m, std::sqrt(2.0) * sigma, 1e-12);
  // 435 pairs of 30 independent tags: the pairs share tags, so the sample
  // mean's spread is ~ sqrt(2/30) ~ 0.26 rather than 1/sqrt(435); bounds at
  // about 2 of those, the std within 25 %.
  EXPECT_NEAR(lengths.normalized_mean, 0.0, 0.5);
  EXPECT_GT(lengths.normalized_std, 0.75);
  EXPECT_LT(lengths.normalized_std, 1.25);
  EXPECT_LT(lengths.beyond_3_sigma, 0.03);
}

// A map 100 ppm too large whose tag 7 is 2 mm off, with the covariance
// saying so (sigma 2 mm against 20 um for the others): the plain slope reads
// tag 7's error as scale, the weighted one finds the 100 ppm.
TEST(LengthErrors, WeightedSlopeCountsEachPairByItsSigma) {
  const TargetCornerMap truth = BoxTargets();
  TargetCornerMap estimate = Transformed(truth, 1.0001, Eigen::Quaterniond::Identity(), Eigen::Vector3d::Zero());
  const Eigen::Vector3d away = (TagCenter(estimate.at(7)) - TagCenter(estimate.at(20))).normalized();
  for (Eigen::Vector3d& c : estimate.at(7)) c += 0.002 * away;
  TagCovariance covariance;
  for (const auto& [id, corners] : truth) covariance.ids.push_back(id);
  const int n = 6 * static_cast<int>(covariance.ids.size());
  covariance.covariance = Eigen::MatrixXd::Zero(n, n);
  for (int i = 0; i < n; i += 6) {
    const double sigma = covariance.ids[static_cast<size_t>(i / 6)] == 7 ? 0.002 : 2e-5;
    covariance.covariance.block<3, 3>(i + 3, i + 3) = sigma * sigma * Eigen::Matrix3d::Identity();
  }
  // A common scale term in every sigma (a print tolerance) changes nothing.
  for (const double scale_sigma_rel : {0.0, 2e-4}) {
    const LengthErrors lengths = CompareLengths(truth, estimate, covariance, scale_sigma_rel);
    ASSERT_TRUE(lengths.weighted_error_per_length_ppm.has_value());
    // Tag 7's 29 pairs of 435 carry up to 2 mm over ~1 m: tens of ppm on
    // the plain slope; on the weighted one 1/10,000 of their weight.
    EXPECT_GT(std::abs(lengths.error_per_length_ppm - 100.0), 20.0);
    EXPECT_NEAR(*lengths.weighted_error_per_length_ppm, 100.0, 1.0) << scale_sigma_rel;
  }
  EXPECT_FALSE(CompareLengths(truth, estimate, std::nullopt).weighted_error_per_length_ppm.has_value());
}

TEST(MapPrecision, RatioAndScaleOfAKnownSimilarity) {
  EvaluationInput in;
  const TargetCornerMap truth = BoxTargets();
  in.true_targets = truth;
  // 1000 ppm too small, rotated and moved; one tag 1 mm off along z.
  const Eigen::Quaterniond rotation(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitY()));
  TargetCornerMap estimate = Transformed(truth, 0.999, rotation, Eigen::Vector3d(1, 2, 3));
  const Evaluation exact = [&] {
    EvaluationInput e = in;
    e.estimated_targets = estimate;
    return Evaluate(e);
  }();
  ASSERT_TRUE(exact.map.has_value());
  // true_from_est's scale is 1/0.999: +1001 ppm.
  EXPECT_NEAR(exact.map->scale_error_ppm, 1e6 / 0.999 - 1e6, 1e-3);
  EXPECT_LT(exact.map->similarity_rms_m, 1e-9);
  Eigen::Vector3d low = truth.begin()->second[0], high = low;
  for (const auto& [id, corners] : truth) {
    for (const Eigen::Vector3d& p : corners) {
      low = low.cwiseMin(p);
      high = high.cwiseMax(p);
    }
  }
  EXPECT_NEAR(exact.map->scene_size_m, (high - low).norm(), 1e-12);
  // The rigid fit keeps the scale error: the RMS is at least what 1000 ppm
  // leaves on a map of this size (a few tenths of a millimetre).
  EXPECT_GT(exact.map->rigid_rms_m, 1e-4);
  EXPECT_NEAR(exact.map->rigid_ratio, exact.map->scene_size_m / exact.map->rigid_rms_m, 1e-9);
  ASSERT_TRUE(exact.lengths.has_value());
  EXPECT_NEAR(exact.lengths->error_per_length_ppm, -1000.0, 1e-6);
}

}  // namespace
}  // namespace tagsfm::eval
