// The evaluator against perturbations whose errors are known in closed form.
#include <gtest/gtest.h>

#include <cmath>

#include "tagsfm/eval/evaluation.h"
#include "test_camera.h"

namespace tagsfm::eval {
namespace {

constexpr double kDeg = M_PI / 180;

CameraModel TestCamera() { return testing::PinholeCamera(640, 480, 500, 319.5, 239.5); }

// Eight tags on two walls and five cameras looking at them from 2 m.
EvaluationInput TruthAsResult() {
  EvaluationInput in;
  in.camera = TestCamera();
  TargetCornerMap targets;
  for (int id = 0; id < 8; ++id) {
    const Eigen::Vector3d centre(-0.6 + 0.17 * id, 0.1 * (id % 3), 1.0 + 0.1 * (id % 2));
    const double h = 0.03;
    targets[id] = {centre + Eigen::Vector3d(-h, 0, -h), centre + Eigen::Vector3d(h, 0, -h),
                   centre + Eigen::Vector3d(h, 0, h), centre + Eigen::Vector3d(-h, 0, h)};
  }
  PoseMap poses;
  for (int f = 0; f < 5; ++f) {
    // Camera looking along +y (world z up): x_cam = x, y_cam = -z, z_cam = y.
    Eigen::Matrix3d looking_along_y;
    looking_along_y << 1, 0, 0, 0, 0, -1, 0, 1, 0;
    const Eigen::Quaterniond yaw(Eigen::AngleAxisd((f - 2) * 10 * kDeg, Eigen::Vector3d::UnitZ()));
    const Eigen::Quaterniond cam_from_world = Eigen::Quaterniond(looking_along_y) * yaw.conjugate();
    const Eigen::Vector3d centre = yaw * Eigen::Vector3d(0, -2.0, 0) + Eigen::Vector3d(0, 0, 1.05);
    poses[f] = Rigid3d(cam_from_world, -(cam_from_world * centre));
  }
  in.true_targets = targets;
  in.estimated_targets = targets;
  in.true_poses = poses;
  in.estimated_poses = poses;
  in.surfaces = std::vector<SurfaceRectangle>{{"wall", {-2, 0, 0}, {4, 0, 0}, {0, 0, 2.5}}};
  in.cloud = std::vector<Eigen::Vector3d>{{0, 0, 1}, {0.5, 0, 0.5}, {-1, 0, 2}};
  return in;
}

const AlignedErrors& Variant(const Evaluation& e, const std::string& name) {
  for (const AlignedErrors& v : e.variants) {
    if (v.name == name) return v;
  }
  throw std::runtime_error("no variant " + name);
}

TEST(Evaluate, TruthAgainstItselfIsExact) {
  const Evaluation e = Evaluate(TruthAsResult());
  EXPECT_EQ(e.ground_truth_frames, 5);
  EXPECT_EQ(e.registered_frames, 5);
  EXPECT_EQ(e.alignment_source, "target_corners");
  ASSERT_EQ(e.variants.size(), 3u);
  for (const AlignedErrors& v : e.variants) {
    EXPECT_NEAR(v.poses->position_m.max, 0, 1e-9) << v.name;
    EXPECT_NEAR(v.poses->rotation_deg.max, 0, 1e-5) << v.name;
    EXPECT_NEAR(v.poses->reprojection_px.max, 0, 1e-6) << v.name;
    EXPECT_NEAR(v.targets->corner_error_m.max, 0, 1e-9) << v.name;
    EXPECT_NEAR(v.cloud_distance_m->max, 0, 1e-9) << v.name;
  }
  EXPECT_EQ(Variant(e, "as_is").poses->reprojection_px.count, 5);  // every frame sees corners
}

TEST(Evaluate, OneCameraRotatedByATenthOfADegree) {
  EvaluationInput in = TruthAsResult();
  const double angle = 0.1 * kDeg;
  Rigid3d& pose = in.estimated_poses->at(2);
  // Rotate about the camera centre so the centre stays put (eq. 3 stays 0).
  const Eigen::Vector3d centre = pose.Center();
  pose.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(angle, Eigen::Vector3d::UnitY())) * pose.rotation;
  pose.translation = -(pose.rotation * centre);
  const Evaluation e = Evaluate(in);
  const PoseErrors& errors = *Variant(e, "as_is").poses;
  const FrameError& frame2 = errors.frames[2];
  EXPECT_NEAR(frame2.rotation_deg, 0.1, 1e-9);
  // ||q_d q - q|| = ||q_d - 1|| = 2 sin(angle / 4) for unit q.
  EXPECT_NEAR(frame2.rotation_rel, 2 * std::sin(angle / 4), 1e-12);
  EXPECT_NEAR(frame2.position_m, 0, 1e-12);
  // A pan by 0.1 degree about the camera's y axis moves a point seen at
  // angle a off-axis by fx (tan(a + 0.1 deg) - tan a) ~ fx tan(0.1 deg) / cos^2 a:
  // 0.873 px on the axis, 0.988 px at 20 degrees (the widest corner here).
  EXPECT_GE(*frame2.reprojection_px, 500 * std::tan(angle));
  EXPECT_LE(*frame2.reprojection_px, 500 * std::tan(angle) / std::pow(std::cos(20 * kDeg), 2));
  EXPECT_NEAR(errors.rotation_deg.max, 0.1, 1e-9);
  EXPECT_NEAR(errors.rotation_deg.mean, 0.1 / 5, 1e-9);
  EXPECT_NEAR(errors.rotation_deg.median, 0, 1e-9);
}

TEST(Evaluate, OneCameraShiftedByOneMillimetre) {
  EvaluationInput in = TruthAsResult();
  Rigid3d& pose = in.estimated_poses->at(4);
  // 1 mm along the camera's own x axis: the centre moves sideways.
  pose.translation -= Eigen::Vector3d(0.001, 0, 0);
  const Evaluation e = Evaluate(in);
  const PoseErrors& errors = *Variant(e, "as_is").poses;
  EXPECT_NEAR(errors.frames[4].position_m, 0.001, 1e-12);
  EXPECT_NEAR(errors.position_m.max, 0.001, 1e-12);
  EXPECT_NEAR(errors.position_m.mean, 0.0002, 1e-12);
  EXPECT_NEAR(errors.frames[4].rotation_deg, 0, 1e-9);
  // A sideways shift d moves a point at depth z by fx d / z: the corners are
  // 1.7 to 2.4 m deep.
  EXPECT_GT(*errors.frames[4].reprojection_px, 500 * 0.001 / 2.4);
  EXPECT_LT(*errors.frames[4].reprojection_px, 500 * 0.001 / 1.7);
}

TEST(Evaluate, MapScaledBy1001IsUndoneBySimilarityOnly) {
  EvaluationInput in = TruthAsResult();
  const double s = 1.001;
  double sum_sq = 0;
  int n = 0;
  for (auto& [id, corners] : *in.estimated_targets) {
    for (auto& c : corners) {
      sum_sq += std::pow((s - 1) * c.norm(), 2);
      ++n;
      c *= s;
    }
  }
  for (auto& [frame, pose] : *in.estimated_poses) pose.translation *= s;  // centres scale with the world
  for (auto& p : *in.cloud) p *= s;
  const Evaluation e = Evaluate(in);
  const AlignedErrors& as_is = Variant(e, "as_is");
  EXPECT_NEAR(as_is.targets->corner_error_m.rms, std::sqrt(sum_sq / n), 1e-12);
  EXPECT_NEAR(as_is.poses->position_m.max, (s - 1) * 2.27, 0.0005);  // centres ~2.2 m from the origin
  EXPECT_NEAR(as_is.poses->rotation_deg.max, 0, 1e-9);
  const AlignedErrors& sim = Variant(e, "similarity");
  EXPECT_NEAR(sim.true_from_est.scale, 1 / s, 1e-12);
  EXPECT_NEAR(sim.targets->corner_error_m.max, 0, 1e-12);
  EXPECT_NEAR(sim.poses->position_m.max, 0, 1e-12);
  EXPECT_NEAR(sim.poses->reprojection_px.max, 0, 1e-9);
  EXPECT_NEAR(sim.cloud_distance_m->max, 0, 1e-12);
  // A rigid fit cannot undo a scale: the residual stays, smaller than as is.
  const AlignedErrors& rigid = Variant(e, "rigid");
  EXPECT_GT(rigid.targets->corner_error_m.rms, 1e-5);
  EXPECT_LE(rigid.targets->corner_error_m.rms, as_is.targets->corner_error_m.rms + 1e-12);
}

TEST(Evaluate, ResultInAnotherFrameIsRecoveredByRigidAlignment) {
  EvaluationInput in = TruthAsResult();
  Sim3d est_from_true;
  est_from_true.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()));
  est_from_true.translation = Eigen::Vector3d(0.3, -1.2, 0.5);
  for (auto& [id, corners] : *in.estimated_targets) {
    for (auto& c : corners) c = est_from_true * c;
  }
  // cam_from_est = cam_from_true * true_from_est.
  const Rigid3d true_from_est = Rigid3d(est_from_true.rotation, est_from_true.translation).Inverse();
  for (auto& [frame, pose] : *in.estimated_poses) pose = pose * true_from_est;
  const Evaluation e = Evaluate(in);
  EXPECT_GT(Variant(e, "as_is").poses->position_m.max, 0.1);
  const AlignedErrors& rigid = Variant(e, "rigid");
  EXPECT_NEAR(rigid.poses->position_m.max, 0, 1e-9);
  EXPECT_NEAR(rigid.poses->rotation_deg.max, 0, 1e-5);
  EXPECT_NEAR(rigid.targets->corner_error_m.max, 0, 1e-9);
}

TEST(Evaluate, UnregisteredFramesAndMissingTagsAreCounted) {
  EvaluationInput in = TruthAsResult();
  in.estimated_poses->erase(1);
  in.estimated_poses->erase(3);
  (*in.estimated_poses)[99] = in.true_poses->at(0);
  in.estimated_targets->erase(5);
  const Evaluation e = Evaluate(in);
  EXPECT_EQ(e.registered_frames, 3);
  EXPECT_EQ(e.unregistered_frames, 2);
  EXPECT_EQ(e.unknown_frames, 1);
  EXPECT_EQ(e.missing_tags, std::vector<TagId>{5});
  EXPECT_EQ(Variant(e, "as_is").poses->frames.size(), 3u);
}

TEST(Evaluate, WithoutTargetsAlignsOnCameraCentres) {
  EvaluationInput in = TruthAsResult();
  in.estimated_targets.reset();
  for (auto& [frame, pose] : *in.estimated_poses) pose.translation *= 2.0;
  const Evaluation e = Evaluate(in);
  EXPECT_EQ(e.alignment_source, "camera_centres");
  EXPECT_NEAR(Variant(e, "similarity").true_from_est.scale, 0.5, 1e-12);
  EXPECT_NEAR(Variant(e, "similarity").poses->position_m.max, 0, 1e-12);
}

TEST(Stats, MeanMedianP95Max) {
  const Stats s = Stats::Of({4, 1, 3, 2});
  EXPECT_EQ(s.count, 4);
  EXPECT_DOUBLE_EQ(s.mean, 2.5);
  EXPECT_DOUBLE_EQ(s.median, 2.5);
  EXPECT_DOUBLE_EQ(s.max, 4);
  EXPECT_DOUBLE_EQ(s.p95, 4);
  EXPECT_DOUBLE_EQ(s.rms, std::sqrt(7.5));
  EXPECT_EQ(Stats::Of({}).count, 0);
}

}  // namespace
}  // namespace tagsfm::eval
