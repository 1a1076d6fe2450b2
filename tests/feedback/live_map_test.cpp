// The dashboard's top view: target centres, camera centre, viewing direction
// and path in the world, from registered frames' poses and the tags' views.
#include "tagsfm/feedback/live_map.h"

#include <cmath>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "tagsfm/feedback/live_feedback.h"
#include "test_camera.h"

namespace tagsfm {
namespace {

constexpr double kTagSize = 0.1;

CameraModel Camera() { return testing::PinholeCamera(1280, 720, 1000, 640, 360); }

// A wall of tags in the plane x = 0 facing +x (world z is up), seen by a
// level camera at `azimuth_deg` round the z axis, 2 m from the wall's axis,
// at `height_m`, looking horizontally towards the axis.
Rigid3d LevelCamera(double azimuth_deg, double height_m) {
  const double a = azimuth_deg * M_PI / 180;
  const Eigen::Vector3d centre(2 * std::cos(a), 2 * std::sin(a), height_m);
  const Eigen::Vector3d z = -Eigen::Vector3d(centre.x(), centre.y(), 0).normalized();
  const Eigen::Vector3d y = -Eigen::Vector3d::UnitZ();
  Eigen::Matrix3d world_from_cam;
  world_from_cam << y.cross(z), y, z;
  const Eigen::Quaterniond cam_from_world(world_from_cam.transpose());
  return Rigid3d(cam_from_world, -(cam_from_world * centre));
}

std::vector<Eigen::Vector3d> WallCentres() {
  std::vector<Eigen::Vector3d> centres;
  for (int i = 0; i < 6; ++i) centres.emplace_back(0.0, 0.3 * (i % 3) - 0.3, 0.3 * (i / 3) - 0.15);
  return centres;
}

DetectionSet SeeTheWall(const Rigid3d& cam_from_world, FrameId frame) {
  Eigen::Matrix3d world_from_tag;  // tag x along world y, tag y along world z, normal +x
  world_from_tag << 0, 0, 1, 1, 0, 0, 0, 1, 0;
  const double h = kTagSize / 2;
  const Eigen::Vector3d local[4] = {{-h, -h, 0}, {h, -h, 0}, {h, h, 0}, {-h, h, 0}};
  DetectionSet set;
  set.frame = frame;
  const auto centres = WallCentres();
  for (size_t id = 0; id < centres.size(); ++id) {
    TagDetection tag;
    tag.id = static_cast<TagId>(id);
    for (int c = 0; c < 4; ++c) tag.corners[c] = Camera().Project(cam_from_world * (centres[id] + world_from_tag * local[c]));
    set.tags.push_back(tag);
  }
  return set;
}

TEST(LiveMap, PlacesTargetsAndTheCameraInTheWorld) {
  TargetConfig targets;
  targets.size_m = kTagSize;
  LiveFeedback feedback(Camera(), targets, LiveFeedbackOptions{});
  FrameId frame = 0;
  for (double azimuth : {-30.0, -10.0, 10.0, 35.0}) {
    FrameReport report;
    report.frame = frame;
    report.registered = true;
    report.cam_from_world = LevelCamera(azimuth, 0.4);
    feedback.Update(SeeTheWall(report.cam_from_world, frame), report, frame * 33'333'333);
    ++frame;
  }
  const LiveMap& map = feedback.status().map;
  ASSERT_EQ(map.targets.size(), 6u);
  // Exact projections: each tag's own pose is exact to the solver's
  // tolerance (the coverage test holds distances to 1e-6 m).
  for (const MapTarget& t : map.targets) EXPECT_LT((t.centre_in_world - WallCentres()[t.id]).norm(), 1e-5) << t.id;
  const Rigid3d last = LevelCamera(35.0, 0.4);
  ASSERT_TRUE(map.camera_in_world && map.camera_axis_in_world);
  EXPECT_LT((*map.camera_in_world - last.Center()).norm(), 1e-12);
  const Eigen::Vector3d toward_axis = -Eigen::Vector3d(last.Center().x(), last.Center().y(), 0).normalized();
  EXPECT_LT((*map.camera_axis_in_world - toward_axis).norm(), 1e-12);
  ASSERT_EQ(map.camera_path.size(), 4u);
  EXPECT_LT((map.camera_path.front() - LevelCamera(-30.0, 0.4).Center()).norm(), 1e-12);
  // A level camera: the top view looks down world z, x along the first camera's right.
  EXPECT_LT(std::abs(map.top_x.dot(Eigen::Vector3d::UnitZ())), 1e-12);
  EXPECT_LT(std::abs(map.top_y.dot(Eigen::Vector3d::UnitZ())), 1e-12);
  EXPECT_NEAR(map.top_x.cross(map.top_y).dot(Eigen::Vector3d::UnitZ()), 1.0, 1e-12);
  EXPECT_GT(map.top_x.dot(LevelCamera(-30.0, 0.4).Inverse().rotation * Eigen::Vector3d::UnitX()), 0.999);

  // The JSON the page reads.
  const auto json = nlohmann::json::parse(LiveStatusJson(feedback.status()));
  ASSERT_EQ(json["map"]["targets"].size(), 6u);
  EXPECT_NEAR(json["map"]["targets"][4]["xyz"][1].get<double>(), WallCentres()[4].y(), 1e-4);
  EXPECT_EQ(json["map"]["path"].size(), 4u);
  EXPECT_NEAR(json["map"]["camera"][2].get<double>(), 0.4, 1e-4);
  // The goals the page colours the targets by are the warnings' own.
  EXPECT_EQ(json["goals"]["min_views_per_target"], LiveFeedbackOptions{}.min_views_per_target);
  EXPECT_EQ(json["goals"]["min_direction_spread_deg"], LiveFeedbackOptions{}.min_direction_spread_deg);
  EXPECT_EQ(json["goals"]["point_error_m"], LiveFeedbackOptions{}.point_error_goal_m);

  // A frame without a pose: no current camera, the map and path stay.
  FrameReport lost;
  lost.frame = frame;
  feedback.Update(SeeTheWall(last, frame), lost, frame * 33'333'333);
  EXPECT_FALSE(feedback.status().map.camera_in_world);
  EXPECT_EQ(feedback.status().map.camera_path.size(), 4u);
  EXPECT_EQ(feedback.status().map.targets.size(), 6u);
  EXPECT_TRUE(nlohmann::json::parse(LiveStatusJson(feedback.status()))["map"]["camera"].is_null());
}

TEST(LiveMap, CameraPathStaysBoundedAndEvenInTime) {
  LiveMapTracker tracker;
  constexpr int kFrames = 5000;
  for (int f = 0; f < kFrames; ++f) {
    FrameReport report;
    report.registered = true;
    report.cam_from_world = Rigid3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(-f, 0, 0));  // centre (f, 0, 0)
    tracker.Add(report, {});
    ASSERT_LT(tracker.map().camera_path.size(), kMaxCameraPathPoints);
  }
  const auto& path = tracker.map().camera_path;
  // 5000 frames in fewer than 512 points: every 16th frame, from the first.
  ASSERT_GE(path.size(), kMaxCameraPathPoints / 2);
  EXPECT_EQ(path.front().x(), 0);
  for (size_t i = 1; i < path.size(); ++i) EXPECT_EQ(path[i].x() - path[i - 1].x(), 16) << i;
  EXPECT_GT(path.back().x(), kFrames - 16 - 1);
}

}  // namespace
}  // namespace tagsfm
