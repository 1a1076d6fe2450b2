#include <gtest/gtest.h>

#include <random>

#include "tagsfm/eval/similarity.h"

namespace tagsfm::eval {
namespace {

TEST(EstimateSim3d, RecoversAKnownSimilarity) {
  Sim3d truth;
  truth.scale = 0.37;
  truth.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(2.1, Eigen::Vector3d(-1, 0.5, 2).normalized()));
  truth.translation = Eigen::Vector3d(4, -2, 0.25);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-2, 2);
  std::vector<Eigen::Vector3d> src, dst;
  for (int i = 0; i < 20; ++i) {
    src.emplace_back(u(rng), u(rng), u(rng));
    dst.push_back(truth * src.back());
  }
  Result<Sim3d> sim = EstimateSim3d(src, dst, true);
  ASSERT_TRUE(sim) << sim.error().message;
  EXPECT_NEAR(sim->scale, 0.37, 1e-12);
  EXPECT_NEAR(sim->rotation.angularDistance(truth.rotation), 0, 1e-9);
  EXPECT_NEAR((sim->translation - truth.translation).norm(), 0, 1e-9);
  // Without scale: the best rigid fit, whose residual cannot vanish.
  Result<Sim3d> rigid = EstimateSim3d(src, dst, false);
  ASSERT_TRUE(rigid);
  EXPECT_EQ(rigid->scale, 1.0);
  EXPECT_NEAR(rigid->rotation.angularDistance(truth.rotation), 0, 1e-9);
}

TEST(EstimateSim3d, RejectsTooFewOrCollinearPoints) {
  EXPECT_FALSE(EstimateSim3d({{0, 0, 0}, {1, 0, 0}}, {{0, 0, 0}, {1, 0, 0}}, true));
  EXPECT_FALSE(EstimateSim3d({{0, 0, 0}, {1, 0, 0}, {2, 0, 0}}, {{0, 0, 0}, {1, 0, 0}, {2, 0, 0}}, true));
}

TEST(Sim3d, TransformPoseKeepsProjectionsOfTransformedPoints) {
  Sim3d true_from_est;
  true_from_est.scale = 2.5;
  true_from_est.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitZ()));
  true_from_est.translation = Eigen::Vector3d(1, 2, 3);
  const Rigid3d cam_from_est(Eigen::Quaterniond(Eigen::AngleAxisd(-0.3, Eigen::Vector3d::UnitX())), {0.1, 0.2, 2});
  const Rigid3d cam_from_true = true_from_est.TransformPose(cam_from_est);
  const Eigen::Vector3d point_est(0.3, -0.4, 0.5);
  const Eigen::Vector3d a = cam_from_est * point_est, b = cam_from_true * (true_from_est * point_est);
  EXPECT_NEAR((b - 2.5 * a).norm(), 0, 1e-12);  // same ray, scaled
  EXPECT_NEAR((cam_from_true.Center() - true_from_est * cam_from_est.Center()).norm(), 0, 1e-12);
}

}  // namespace
}  // namespace tagsfm::eval
