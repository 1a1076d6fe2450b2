// The incremental mapper on exact synthetic correspondences: each 3D point
// has its own random descriptor, seen by every view it projects into, so
// matching, verification, registration, triangulation and adjustment are
// tested without rendering; and degenerate input.
#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "tagsfm/eval/similarity.h"
#include "tagsfm/sfm/incremental_mapper.h"
#include "look_at.h"
#include "test_camera.h"

namespace tagsfm::sfm {
namespace {

struct SyntheticSet {
  CameraModel camera = testing::PinholeCamera(1280, 720, 1000, 639.5, 359.5);
  std::vector<Eigen::Vector3d> points;
  std::vector<Rigid3d> poses;
  std::vector<KeyframeFeatures> views;
  std::vector<std::vector<int>> true_point;  // view, feature -> index into points
};

// Points on a 1 m cube's surface; cameras on an arc at 2.5 m looking at it.
// Pixel noise `noise_px`; a descriptor per point (unit, random), shared by its views.
SyntheticSet MakeSet(int frames, double arc_deg, double noise_px, bool pure_rotation, unsigned seed) {
  SyntheticSet s;
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-0.5, 0.5);
  std::normal_distribution<double> gauss(0.0, 1.0);
  const int n_points = 1000;
  cv::Mat descriptors(n_points, 128, CV_32F);
  for (int i = 0; i < n_points; ++i) {
    Eigen::Vector3d x(u(rng), u(rng), u(rng));
    x[i % 3] = (i / 3) % 2 ? 0.5 : -0.5;  // on a face
    s.points.push_back(x);
    for (int c = 0; c < 128; ++c) descriptors.at<float>(i, c) = static_cast<float>(std::abs(gauss(rng)));
    cv::normalize(descriptors.row(i), descriptors.row(i));
  }
  for (int f = 0; f < frames; ++f) {
    const double azimuth = (arc_deg * f / std::max(1, frames - 1) - arc_deg / 2) * M_PI / 180;
    const Eigen::Vector3d centre = pure_rotation ? Eigen::Vector3d(0, -0.3, -2.5)
                                                 : Eigen::Vector3d(2.5 * std::sin(azimuth), -0.3, -2.5 * std::cos(azimuth));
    const Eigen::Vector3d target = pure_rotation ? Eigen::Vector3d(centre + Eigen::Vector3d(std::sin(azimuth), 0.1, std::cos(azimuth)))
                                                 : Eigen::Vector3d::Zero();
    const Rigid3d pose = LookingAt(centre, target);
    s.poses.push_back(pose);
    KeyframeFeatures view;
    view.frame = f;
    std::vector<int> rows;
    for (int i = 0; i < n_points; ++i) {
      const Eigen::Vector3d p = pose * s.points[static_cast<size_t>(i)];
      if (p.z() < 0.1) continue;
      // Drawn one by one: the order of a call's arguments is the compiler's choice.
      const double noise_x = gauss(rng);
      const double noise_y = gauss(rng);
      const Eigen::Vector2d px = s.camera.Project(p) + noise_px * Eigen::Vector2d(noise_x, noise_y);
      if (px.x() < 0 || px.y() < 0 || px.x() > 1279 || px.y() > 719) continue;
      view.pixels.push_back(px);
      view.rgb.push_back({128, 128, 128});
      view.scale.push_back(4);
      view.orientation.push_back(0);
      rows.push_back(i);
    }
    cv::Mat unit(static_cast<int>(rows.size()), 128, CV_32F);
    for (size_t r = 0; r < rows.size(); ++r) descriptors.row(rows[r]).copyTo(unit.row(static_cast<int>(r)));
    view.descriptors = QuantiseDescriptors(unit);
    s.views.push_back(std::move(view));
    s.true_point.push_back(rows);
  }
  return s;
}

TEST(SfmMapper, SyntheticCorrespondencesGiveTheTruePosesAndPoints) {
  // 0.5 px noise: after the similarity fit, centres within 2 mm and points
  // within 5 mm at 2.5 m with f = 1000 (0.5 px is 1.25 mm across the ray;
  // along it, at 10-70 degrees of triangulation angle, up to about 4x
  // that). Exact input gives far less.
  for (double noise : {0.0, 0.5}) {
    const SyntheticSet s = MakeSet(8, 70, noise, false, 11);
    auto result = ReconstructIncremental(s.views, s.camera, {});
    ASSERT_TRUE(result.has_value()) << result.error().message;
    const SfmModel& model = result->model;
    ASSERT_EQ(model.RegisteredImages(), 8);
    // The similarity to the truth from the points whose tracks are all one
    // true point (about a thousand): fitted to the 8 camera centres alone,
    // its own error (~2 mm over the 1.4 m of the arc) moved points by as
    // much as the mapper's.
    const auto TruthIndex = [&s](const SfmPoint& point) {
      const int index = s.true_point[point.track.front().image][point.track.front().feature];
      for (const Observation& o : point.track) {
        if (s.true_point[o.image][o.feature] != index) return -1;
      }
      return index;
    };
    std::vector<Eigen::Vector3d> est_points, true_points;
    for (const SfmPoint& point : model.points) {
      const int truth_index = point.deleted ? -1 : TruthIndex(point);
      if (truth_index < 0) continue;
      est_points.push_back(point.xyz);
      true_points.push_back(s.points[truth_index]);
    }
    auto sim = eval::EstimateSim3d(est_points, true_points, true);
    ASSERT_TRUE(sim.has_value());
    std::vector<Eigen::Vector3d> est, truth;
    for (size_t i = 0; i < model.images.size(); ++i) {
      est.push_back(model.images[i].cam_from_world.Center());
      truth.push_back(s.poses[i].Center());
    }
    const double limit = noise == 0 ? 1e-5 : 2e-3;
    for (size_t i = 0; i < est.size(); ++i) EXPECT_LT((*sim * est[i] - truth[i]).norm(), limit) << "view " << i;
    for (size_t i = 0; i < model.images.size(); ++i) {
      const Rigid3d aligned = sim->TransformPose(model.images[i].cam_from_world);
      EXPECT_LT(RotationAngleDeg(aligned.rotation, s.poses[i].rotation), noise == 0 ? 1e-4 : 0.05) << "view " << i;
    }
    // Each point: one true point behind its whole track, and near it.
    int points = 0, close = 0;
    for (const SfmPoint& point : model.points) {
      if (point.deleted) continue;
      ++points;
      const int truth_index = TruthIndex(point);
      close += truth_index >= 0 && (*sim * point.xyz - s.points[truth_index]).norm() < (noise == 0 ? 1e-5 : 5e-3);
    }
    EXPECT_GT(points, 750) << "noise " << noise;
    EXPECT_GT(close, 0.97 * points) << "noise " << noise;
    std::cout << "noise " << noise << ": " << points << " points, " << close << " on their true point; matching "
              << result->stats.matching_s << " s, mapping " << result->stats.mapping_s << " s\n";
  }
}

TEST(SfmMapper, PureRotationIsAOneLineError) {
  const SyntheticSet s = MakeSet(6, 40, 0.3, true, 12);
  auto result = ReconstructIncremental(s.views, s.camera, {});
  ASSERT_FALSE(result.has_value());
  // No pair qualifies, or the chosen one triangulates nothing.
  EXPECT_NE(result.error().message.find("initial pair"), std::string::npos) << result.error().message;
  EXPECT_EQ(result.error().message.find('\n'), std::string::npos);
}

TEST(SfmMapper, NoTextureOrTooFewViewsIsAnError) {
  const CameraModel camera = testing::PinholeCamera(1280, 720, 1000, 639.5, 359.5);
  std::vector<KeyframeFeatures> empty(3);
  for (int i = 0; i < 3; ++i) {
    empty[static_cast<size_t>(i)].frame = i;
    empty[static_cast<size_t>(i)].descriptors = cv::Mat(0, 128, CV_8U);
  }
  auto none = ReconstructIncremental(empty, camera, {});
  ASSERT_FALSE(none.has_value());
  EXPECT_NE(none.error().message.find("0 of 3 view pairs"), std::string::npos) << none.error().message;
  empty.resize(1);
  EXPECT_FALSE(ReconstructIncremental(empty, camera, {}).has_value());
  IncrementalMapperOptions bad;
  bad.ratio = 1.5;
  auto checked = ReconstructIncremental(MakeSet(3, 30, 0, false, 1).views, camera, bad);
  ASSERT_FALSE(checked.has_value());
  EXPECT_NE(checked.error().message.find("sfm.ratio"), std::string::npos);
}

TEST(SfmMapper, AnUnrelatedViewStaysUnregisteredWithAReason) {
  SyntheticSet s = MakeSet(6, 50, 0.3, false, 13);
  // View 3 sees other points: descriptors no other view has.
  std::mt19937 rng(5);
  std::normal_distribution<double> gauss(0.0, 1.0);
  cv::Mat other(s.views[3].descriptors.rows, 128, CV_32F);
  for (int r = 0; r < other.rows; ++r) {
    for (int c = 0; c < 128; ++c) other.at<float>(r, c) = static_cast<float>(std::abs(gauss(rng)));
    cv::normalize(other.row(r), other.row(r));
  }
  s.views[3].descriptors = QuantiseDescriptors(other);
  auto result = ReconstructIncremental(s.views, s.camera, {});
  ASSERT_TRUE(result.has_value()) << result.error().message;
  EXPECT_EQ(result->model.RegisteredImages(), 5);
  EXPECT_FALSE(result->model.images[3].registered);
  EXPECT_NE(result->model.images[3].reason.find("not registered"), std::string::npos);
}

}  // namespace
}  // namespace tagsfm::sfm
