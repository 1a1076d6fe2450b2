// Eq. 1-3 and the summary statistics, against hand-computed values.
#include <cmath>
#include <limits>
#include <numbers>

#include <gtest/gtest.h>

#include "tagsfm/analysis/metrics.h"
#include "tagsfm/analysis/statistics.h"
#include "tagsfm/analysis/synthetic_scene.h"
#include "tagsfm/synth/camera_path.h"

namespace tagsfm::analysis {
namespace {

TEST(AnalysisMetrics, RotationalErrorIsSignInvariantAndTwoSinQuarterAngle) {
  const Eigen::Quaterniond truth(Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 2, 3).normalized()));
  const Eigen::Quaterniond same_flipped(-truth.w(), -truth.x(), -truth.y(), -truth.z());
  EXPECT_NEAR(RotationalError(same_flipped, truth), 0.0, 1e-15);
  const double angle = 0.2;
  const Eigen::Quaterniond turned = Eigen::Quaterniond(Eigen::AngleAxisd(angle, Eigen::Vector3d::UnitY())) * truth;
  EXPECT_NEAR(RotationalError(turned, truth), 2 * std::sin(angle / 4), 1e-12);
  const Eigen::Quaterniond turned_flipped(-turned.w(), -turned.x(), -turned.y(), -turned.z());
  EXPECT_NEAR(RotationalError(turned_flipped, truth), 2 * std::sin(angle / 4), 1e-12);
}

TEST(AnalysisMetrics, ComparePosesUsesCameraCentres) {
  const Rigid3d truth = synth::LookAt(Eigen::Vector3d(5, 0, 1), Eigen::Vector3d::Zero(), 0.0);
  const Rigid3d moved = synth::LookAt(Eigen::Vector3d(5, 0.3, 1.4), Eigen::Vector3d::Zero(), 0.0);
  const PoseErrors errors = ComparePoses(moved, truth);
  EXPECT_NEAR(errors.position, 0.5, 1e-12);  // |(0, 0.3, 0.4)|
  EXPECT_GT(errors.rotation_deg, 0.0);
  EXPECT_NEAR(errors.rotation_eq2, 2 * std::sin(errors.rotation_deg * std::numbers::pi / 180 / 4), 1e-12);
}

TEST(AnalysisMetrics, ReprojectionErrorIsTheMeanPixelDistance) {
  const CameraModel camera = ExperimentCamera();
  const Rigid3d cam_from_world;
  const std::vector<Eigen::Vector3d> points = {{0, 0, 2}, {0.2, 0, 2}};
  const std::vector<Eigen::Vector2d> observed = {{camera.cx + 3, camera.cy + 4}, {camera.cx + 100, camera.cy}};
  EXPECT_NEAR(MeanReprojectionError(cam_from_world, points, observed,
                                    [&](const Eigen::Vector3d& p) { return ProjectToPixel(camera, p); }),
              (5.0 + 0.0) / 2, 1e-12);
}

TEST(AnalysisMetrics, LookAtPutsTheTargetOnTheOpticalAxisUpright) {
  const Rigid3d cam_from_world = synth::LookAt(Eigen::Vector3d(3, -4, 2), Eigen::Vector3d(0, 0, 1), 0.0);
  const Eigen::Vector3d target_in_cam = cam_from_world * Eigen::Vector3d(0, 0, 1);
  EXPECT_NEAR(target_in_cam.head<2>().norm(), 0.0, 1e-12);
  EXPECT_GT(target_in_cam.z(), 0.0);
  // A point above the target appears higher in the image (smaller y).
  EXPECT_LT((cam_from_world * Eigen::Vector3d(0, 0, 2)).y(), 0.0);
}

TEST(AnalysisStatistics, SummarizeKnownValues) {
  const Summary odd = Summarize({3, 1, 2, std::numeric_limits<double>::quiet_NaN()});
  EXPECT_EQ(odd.count, 3);
  EXPECT_DOUBLE_EQ(odd.mean, 2.0);
  EXPECT_DOUBLE_EQ(odd.median, 2.0);
  EXPECT_DOUBLE_EQ(odd.std, 1.0);
  EXPECT_DOUBLE_EQ(odd.rms, std::sqrt(14.0 / 3));
  EXPECT_DOUBLE_EQ(Summarize({4, 1, 3, 2}).median, 2.5);
  EXPECT_EQ(Summarize({}).count, 0);
}

TEST(AnalysisScene, VehiclesHaveThePapersCameraCountsAndSeeEnoughPoints) {
  const SyntheticObject bradley = MakeVehicle(VehicleKind::kBradleyLike, 1);
  const SyntheticObject maxxpro = MakeVehicle(VehicleKind::kMaxxproLike, 1);
  EXPECT_EQ(bradley.cameras.size(), 1234u);
  EXPECT_EQ(maxxpro.cameras.size(), 278u);
  const CameraModel camera = ExperimentCamera();
  for (const SyntheticObject* object : {&bradley, &maxxpro}) {
    for (size_t i = 0; i < object->cameras.size(); i += 97) {
      // The sweeps draw up to 1000 points per camera.
      EXPECT_GT(VisiblePoints(object->surface, object->cameras[i], camera).size(), 1000u) << object->name << " camera " << i;
    }
  }
}

}  // namespace
}  // namespace tagsfm::analysis
