#include "tagsfm/feedback/live_feedback.h"

#include <cmath>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "test_camera.h"

namespace tagsfm {
namespace {

constexpr double kTagSize = 0.1;

CameraModel Camera() { return testing::PinholeCamera(1280, 720, 1000, 640, 360); }

TargetConfig Targets() {
  TargetConfig t;
  t.size_m = kTagSize;
  return t;
}

// A tag centred at `centre` (world = camera frame here), its normal pointing
// back at the camera tilted by `tilt_deg` about the tag's x axis then turned
// by `azimuth_deg` about the viewing axis; corners in libapriltag's order.
TagDetection TagAt(TagId id, const Eigen::Vector3d& centre, double tilt_deg, double azimuth_deg = 0) {
  const double h = kTagSize / 2;
  const Eigen::Matrix3d facing = Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitX()).toRotationMatrix();
  const Eigen::Matrix3d rotation = Eigen::AngleAxisd(azimuth_deg * M_PI / 180, Eigen::Vector3d::UnitZ()).toRotationMatrix() *
                                   facing * Eigen::AngleAxisd(tilt_deg * M_PI / 180, Eigen::Vector3d::UnitX()).toRotationMatrix();
  const Eigen::Vector3d local[4] = {{-h, -h, 0}, {h, -h, 0}, {h, h, 0}, {-h, h, 0}};
  TagDetection tag;
  tag.id = id;
  const CameraModel camera = Camera();
  for (int i = 0; i < 4; ++i) tag.corners[i] = camera.Project(centre + rotation * local[i]);
  return tag;
}

TEST(Coverage, TagViewsGiveDistanceAndTiltOfEachTag) {
  DetectionSet set;
  set.tags = {TagAt(1, {0.2, 0.1, 2.0}, 0.0), TagAt(2, {-0.3, 0.0, 1.5}, 35.0)};
  const auto views = ComputeTagViews(Camera(), Targets(), set);
  ASSERT_EQ(views.size(), 2u);
  // Exact projections: the refined tag pose is exact to round-off and solver
  // tolerance, so 1e-6 m and 1e-3 degrees.
  EXPECT_NEAR(views[0].distance_m, Eigen::Vector3d(0.2, 0.1, 2.0).norm(), 1e-6);
  EXPECT_NEAR(views[1].distance_m, Eigen::Vector3d(-0.3, 0.0, 1.5).norm(), 1e-6);
  // Tilt is measured against the ray to the camera, not the optical axis.
  const double off_axis_0 = std::atan2(Eigen::Vector2d(0.2, 0.1).norm(), 2.0) * 180 / M_PI;
  EXPECT_NEAR(views[0].tilt_deg, off_axis_0, 1e-3);
  EXPECT_GT(views[1].tilt_deg, 25.0);
  EXPECT_LT(views[1].tilt_deg, 50.0);
}

TEST(Coverage, TracksTimesSeenSpreadAndSectors) {
  CoverageTracker tracker;
  TagSighting head_on{7, 2.0, 0.0, Eigen::Vector3d(0, 0, 1)};
  tracker.Add(0, {head_on});
  EXPECT_EQ(tracker.targets().at(7).times_seen, 1);
  EXPECT_DOUBLE_EQ(tracker.targets().at(7).direction_spread_deg, 0.0);
  EXPECT_EQ(tracker.targets().at(7).SectorsCovered(), 0);  // head-on has no azimuth
  const double a = 30 * M_PI / 180;
  tracker.Add(1, {TagSighting{7, 2.0, 30.0, Eigen::Vector3d(std::sin(a), 0, std::cos(a))}});
  tracker.Add(2, {TagSighting{7, 2.0, 30.0, Eigen::Vector3d(-std::sin(a), 0, std::cos(a))}});
  const TargetCoverage& c = tracker.targets().at(7);
  EXPECT_EQ(c.times_seen, 3);
  EXPECT_EQ(c.last_seen, 2);
  EXPECT_NEAR(c.direction_spread_deg, 60.0, 1e-9);
  EXPECT_EQ(c.SectorsCovered(), 2);
  EXPECT_NEAR(c.max_tilt_deg, 30.0, 1e-12);
}

FrameReport Registered(int tags_used, double rms_px, size_t mapped) {
  FrameReport report;
  report.registered = true;
  report.tags_used = tags_used;
  report.rms_px = rms_px;
  report.mapped_tags = mapped;
  return report;
}

bool HasWarning(const LiveStatus& status, const std::string& start) {
  for (const auto& w : status.warnings) {
    if (w.text.rfind(start, 0) == 0) return true;
  }
  return false;
}

TEST(LiveFeedback, WarnsAboutTooFewTargetsAndNoPose) {
  LiveFeedback feedback(Camera(), Targets(), LiveFeedbackOptions{});
  DetectionSet set;
  set.frame = 4;
  set.tags = {TagAt(1, {0.1, 0.0, 1.0}, 10.0), TagAt(2, {-0.1, 0.0, 1.0}, 10.0)};
  FrameReport report;
  report.reason = "fewer than 4 correspondences";
  const LiveStatus& status = feedback.Update(set, report, 0);
  EXPECT_FALSE(status.registered);
  EXPECT_EQ(status.targets_in_view, 2);
  EXPECT_TRUE(HasWarning(status, "No camera pose for this frame: fewer than 4")) << status.warnings.front().text;
  EXPECT_TRUE(HasWarning(status, "Only 2 targets in view: need 2 more"));
  EXPECT_TRUE(HasWarning(status, "Seen fewer than 3 times: targets 1, 2"));
}

TEST(LiveFeedback, TellsTheOperatorToMoveCloserWhenFarAway) {
  LiveFeedbackOptions options;
  options.point_error_goal_m = 0.0005;
  std::vector<double> errors, max_depths;
  for (double depth : {1.0, 6.0}) {
    LiveFeedback feedback(Camera(), Targets(), options);
    DetectionSet set;
    for (int i = 0; i < 6; ++i) {
      set.tags.push_back(TagAt(i, {depth * (0.25 * (i % 3) - 0.25), depth * (0.2 * (i / 3) - 0.1), depth}, 5.0));
    }
    const LiveStatus& status = feedback.Update(set, Registered(6, 0.4, 6), 0);
    ASSERT_TRUE(status.predicted_point_error_m && status.max_depth_for_goal_m);
    EXPECT_NEAR(status.depth_m, depth, 0.05 * depth);
    // The model's point error is proportional to depth at a fixed angle, so
    // at max_depth_for_goal it equals the goal.
    EXPECT_NEAR(*status.predicted_point_error_m * *status.max_depth_for_goal_m / status.depth_m,
                options.point_error_goal_m, 1e-3 * options.point_error_goal_m);
    errors.push_back(*status.predicted_point_error_m);
    max_depths.push_back(*status.max_depth_for_goal_m);
    EXPECT_EQ(HasWarning(status, "Move closer"), status.depth_m > *status.max_depth_for_goal_m);
  }
  EXPECT_GT(errors[1], 4.0 * errors[0]);  // six times as far: several times the error
  // Noise estimate from the pose RMS: 0.4 px * sqrt(48/42).
  LiveFeedback feedback(Camera(), Targets(), options);
  DetectionSet set;
  for (int i = 0; i < 6; ++i) set.tags.push_back(TagAt(i, {0.3 * (i % 3) - 0.3, 0.2 * (i / 3) - 0.1, 6.0}, 5.0));
  const LiveStatus& status = feedback.Update(set, Registered(6, 0.4, 6), 0);
  EXPECT_NEAR(status.image_noise_px, 0.4 * std::sqrt(48.0 / 42.0), 1e-12);
  EXPECT_TRUE(HasWarning(status, "Move closer: at 6."));
}

TEST(LiveFeedback, StatusJsonCarriesEveryField) {
  LiveFeedback feedback(Camera(), Targets(), LiveFeedbackOptions{});
  DetectionSet set;
  for (int i = 0; i < 5; ++i) set.tags.push_back(TagAt(i, {0.2 * i - 0.4, 0.0, 2.0}, 10.0));
  feedback.Update(set, Registered(5, 0.2, 5), 0);
  set.frame = 1;
  const auto json = nlohmann::json::parse(LiveStatusJson(feedback.Update(set, Registered(5, 0.2, 5), 33'333'333)));
  EXPECT_EQ(json["frame"], 1);
  EXPECT_NEAR(json["frames_per_second"].get<double>(), 30.0, 1e-6);
  EXPECT_EQ(json["coverage"].size(), 5u);
  EXPECT_EQ(json["coverage"][0]["times_seen"], 2);
  EXPECT_TRUE(json["predicted_point_error_m"].is_number());
  EXPECT_TRUE(json["warnings"].is_array());
}

TEST(LiveFeedback, OptionsCheckNamesTheField) {
  LiveFeedbackOptions options;
  options.point_error_goal_m = 0;
  Status s = options.Check();
  ASSERT_FALSE(s);
  EXPECT_NE(s.error().message.find("point_error_goal_m"), std::string::npos);
}

}  // namespace
}  // namespace tagsfm
