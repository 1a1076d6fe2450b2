// Degenerate geometry for pose estimation and the target map: too few
// correspondences, collinear points, points behind the camera, NaN and
// infinite input, huge coordinates, duplicate tag ids in one frame. Each
// must give an unregistered frame with a reason, or a pose that is right;
// never a crash, never a wrong pose presented as registered.
#include <cmath>
#include <limits>
#include <random>

#include <gtest/gtest.h>

#include "tagsfm/recon/pose_estimator.h"
#include "tagsfm/recon/reconstructor.h"
#include "tagsfm/recon/tag_geometry.h"

namespace tagsfm {
namespace {

constexpr double kF = 500.0;  // focal length, px
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

// A camera 1.2 m from the origin, looking at it from above and to the side.
Rigid3d TruePose() {
  const Eigen::Quaterniond r(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitY()) *
                             Eigen::AngleAxisd(-0.2, Eigen::Vector3d::UnitX()));
  return Rigid3d(r, Eigen::Vector3d(0.05, -0.02, 1.2));
}

// Points on two perpendicular planes, 0.4 m across.
std::vector<Eigen::Vector3d> TwoPlanePoints() {
  std::vector<Eigen::Vector3d> points;
  for (int i = 0; i < 4; ++i) {
    for (int j = 0; j < 3; ++j) {
      points.emplace_back(-0.2 + 0.13 * i, -0.2 + 0.2 * j, 0.0);
      points.emplace_back(-0.2 + 0.13 * i, 0.2, 0.05 + 0.1 * j);
    }
  }
  return points;
}

std::vector<Eigen::Vector2d> Project(const Rigid3d& cam_from_world, const std::vector<Eigen::Vector3d>& points) {
  std::vector<Eigen::Vector2d> normalized;
  for (const auto& p : points) {
    const Eigen::Vector3d c = cam_from_world * p;
    normalized.emplace_back(c.x() / c.z(), c.y() / c.z());
  }
  return normalized;
}

// The property every result must have: unregistered with a reason, or a
// pose within 0.5 degrees and 1 cm of the truth (noise-free input gives
// ~1e-9; the tolerances only allow for the solvers' stopping criteria).
void ExpectRejectedOrRight(const PoseResult& r, const Rigid3d& truth, const std::string& what) {
  if (!r.registered) {
    EXPECT_FALSE(r.reason.empty()) << what << ": unregistered without a reason";
    return;
  }
  EXPECT_LT(RotationAngleDeg(r.cam_from_world.rotation, truth.rotation), 0.5) << what;
  EXPECT_LT((r.cam_from_world.Center() - truth.Center()).norm(), 0.01) << what;
  EXPECT_TRUE(std::isfinite(r.rms_px)) << what;
}

// Registered or not, nothing it returns is NaN.
void ExpectFinite(const PoseResult& r, const std::string& what) {
  if (!r.registered) return;
  EXPECT_TRUE(r.cam_from_world.rotation.coeffs().allFinite()) << what;
  EXPECT_TRUE(r.cam_from_world.translation.allFinite()) << what;
}

TEST(DegenerateGeometry, ZeroToThreeCorrespondencesAreUnregisteredWithReason) {
  const auto points = TwoPlanePoints();
  const auto normalized = Project(TruePose(), points);
  for (size_t n = 0; n <= 3; ++n) {
    const std::vector<Eigen::Vector3d> p(points.begin(), points.begin() + n);
    const std::vector<Eigen::Vector2d> q(normalized.begin(), normalized.begin() + n);
    const PoseResult r = EstimatePose(p, q, kF, kF, std::nullopt, {});
    EXPECT_FALSE(r.registered) << n << " correspondences";
    EXPECT_FALSE(r.reason.empty()) << n << " correspondences";
  }
}

TEST(DegenerateGeometry, MismatchedListsAreUnregisteredWithReason) {
  const auto points = TwoPlanePoints();
  auto normalized = Project(TruePose(), points);
  normalized.pop_back();
  const PoseResult r = EstimatePose(points, normalized, kF, kF, std::nullopt, {});
  EXPECT_FALSE(r.registered);
  EXPECT_FALSE(r.reason.empty());
}

TEST(DegenerateGeometry, CollinearPointsAreUnregistered) {
  // Any rotation about the line fits: no pose can be right, so none may be given.
  std::vector<Eigen::Vector3d> points;
  for (int i = 0; i < 12; ++i) points.emplace_back(-0.3 + 0.05 * i, 0.1, 0.0);
  const PoseResult r = EstimatePose(points, Project(TruePose(), points), kF, kF, std::nullopt, {});
  EXPECT_FALSE(r.registered) << "registered on collinear points";
  EXPECT_FALSE(r.reason.empty());
}

TEST(DegenerateGeometry, AllPointsAtOnePlaceAreUnregistered) {
  const std::vector<Eigen::Vector3d> points(8, Eigen::Vector3d(0.1, 0.2, 0.0));
  const PoseResult r = EstimatePose(points, Project(TruePose(), points), kF, kF, std::nullopt, {});
  EXPECT_FALSE(r.registered);
  EXPECT_FALSE(r.reason.empty());
}

TEST(DegenerateGeometry, CoplanarPointsGiveTheRightPose) {
  // One tag's four corners (a plane, the common case) and a plane of 12
  // points: coplanar is not degenerate, the pose must be right.
  const Rigid3d truth = TruePose();
  const TagCorners tag = TagCornersInWorld(Rigid3d(), 0.1);
  const std::vector<Eigen::Vector3d> corners(tag.begin(), tag.end());
  ExpectRejectedOrRight(EstimatePose(corners, Project(truth, corners), kF, kF, std::nullopt, {}), truth, "one tag");
  const PoseResult one_tag = EstimatePose(corners, Project(truth, corners), kF, kF, std::nullopt, {});
  EXPECT_TRUE(one_tag.registered) << one_tag.reason;
  std::vector<Eigen::Vector3d> plane;
  for (int i = 0; i < 12; ++i) plane.emplace_back(-0.2 + 0.04 * i, -0.2 + 0.35 * (i % 2) + 0.01 * i, 0.0);
  const PoseResult r = EstimatePose(plane, Project(truth, plane), kF, kF, std::nullopt, {});
  EXPECT_TRUE(r.registered) << r.reason;
  ExpectRejectedOrRight(r, truth, "plane of 12");
}

TEST(DegenerateGeometry, PointsBehindTheCameraGiveNoPoseThatPutsThemBehind) {
  // The true camera faces away from the points; their projections (x/z,
  // y/z with z < 0) equal those of the mirrored points in front. A pose may
  // be given only if it puts every inlier in front and reprojects within
  // the RMS limit; the true (backward) pose must never be given.
  const auto points = TwoPlanePoints();
  const Rigid3d facing_away(Eigen::Quaterniond(Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitY())) * TruePose().rotation,
                            Eigen::Vector3d(0.0, 0.0, -1.2));
  for (const auto& p : points) ASSERT_LT((facing_away * p).z(), 0.0);
  const PoseResult r = EstimatePose(points, Project(facing_away, points), kF, kF, std::nullopt, {});
  if (r.registered) {
    for (int i : r.inliers) EXPECT_GT((r.cam_from_world * points[i]).z(), 0.0) << "inlier " << i << " behind";
    EXPECT_LE(r.rms_px, PoseEstimatorOptions().max_rms_px);
  } else {
    EXPECT_FALSE(r.reason.empty());
  }
}

TEST(DegenerateGeometry, NaNAndInfiniteInputNeverGiveAWrongPose) {
  const Rigid3d truth = TruePose();
  const auto points = TwoPlanePoints();
  const auto normalized = Project(truth, points);
  for (double bad : {kNaN, kInf, -kInf}) {
    const std::string what = "value " + std::to_string(bad);
    // One bad image point among 24 good ones.
    auto q = normalized;
    q[5].x() = bad;
    PoseResult r = EstimatePose(points, q, kF, kF, std::nullopt, {});
    ExpectFinite(r, what + " in one image point");
    ExpectRejectedOrRight(r, truth, what + " in one image point");
    // One bad world point.
    auto p = points;
    p[7].z() = bad;
    r = EstimatePose(p, normalized, kF, kF, std::nullopt, {});
    ExpectFinite(r, what + " in one world point");
    ExpectRejectedOrRight(r, truth, what + " in one world point");
    // Every image point bad.
    std::vector<Eigen::Vector2d> all_bad(points.size(), Eigen::Vector2d(bad, bad));
    r = EstimatePose(points, all_bad, kF, kF, std::nullopt, {});
    EXPECT_FALSE(r.registered) << what << " everywhere";
    EXPECT_FALSE(r.reason.empty()) << what << " everywhere";
    // A bad previous pose (a corrupted state) must not spoil a good frame.
    const Rigid3d bad_previous(Eigen::Quaterniond(bad, 0, 0, 0), Eigen::Vector3d(bad, 0, 0));
    r = EstimatePose(points, normalized, kF, kF, bad_previous, {});
    ExpectFinite(r, what + " in the previous pose");
    ExpectRejectedOrRight(r, truth, what + " in the previous pose");
  }
}

TEST(DegenerateGeometry, HugeCoordinatesNeverGiveAWrongPose) {
  // The whole scene 1e9 m away, then a few points 1e12 m off among good ones.
  const auto points = TwoPlanePoints();
  std::vector<Eigen::Vector3d> far = points;
  for (auto& p : far) p += Eigen::Vector3d(1e9, 1e9, 1e9);
  const Rigid3d truth = TruePose();
  const Rigid3d far_truth(truth.rotation, truth.translation - truth.rotation * Eigen::Vector3d(1e9, 1e9, 1e9));
  PoseResult r = EstimatePose(far, Project(far_truth, far), kF, kF, std::nullopt, {});
  ExpectFinite(r, "scene at 1e9 m");
  if (r.registered) {
    EXPECT_LT(RotationAngleDeg(r.cam_from_world.rotation, far_truth.rotation), 0.5);
    // A relative error of 1e-9 on 1.7e9 m: 2 m is what double precision leaves.
    EXPECT_LT((r.cam_from_world.Center() - far_truth.Center()).norm(), 2.0);
  }
  auto p = points;
  p[2] = Eigen::Vector3d(1e12, -1e12, 1e12);
  p[9] = Eigen::Vector3d(-1e12, 1e12, 3e12);
  r = EstimatePose(p, Project(truth, points), kF, kF, std::nullopt, {});
  ExpectFinite(r, "two points at 1e12 m");
  ExpectRejectedOrRight(r, truth, "two points at 1e12 m");
  std::vector<Eigen::Vector2d> q = Project(truth, points);
  q[4] = Eigen::Vector2d(1e15, -1e15);
  r = EstimatePose(points, q, kF, kF, std::nullopt, {});
  ExpectFinite(r, "an image point at 1e15");
  ExpectRejectedOrRight(r, truth, "an image point at 1e15");
}

// --- The map (Reconstructor) ---

constexpr double kTagSize = 0.08;

CameraModel TestCamera() {
  CameraModel c;
  c.width = 640;
  c.height = 480;
  c.fx = c.fy = kF;
  c.cx = 319.5;
  c.cy = 239.5;
  return c;
}

// Six tags: three on the floor, three on a wall.
TargetCornerMap SixTags() {
  TargetCornerMap map;
  const Eigen::Quaterniond wall(Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitX()));
  for (int id = 0; id < 3; ++id) {
    map[id] = TagCornersInWorld(Rigid3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(-0.15 + 0.15 * id, 0, 0)), kTagSize);
    map[id + 3] = TagCornersInWorld(Rigid3d(wall, Eigen::Vector3d(-0.15 + 0.15 * id, 0.2, 0.1)), kTagSize);
  }
  return map;
}

DetectionSet Detect(FrameId frame, const Rigid3d& cam_from_world, const TargetCornerMap& map) {
  const CameraModel camera = TestCamera();
  DetectionSet set;
  set.frame = frame;
  for (const auto& [id, corners] : map) {
    TagDetection tag;
    tag.id = id;
    tag.decision_margin = 80;
    for (int c = 0; c < 4; ++c) tag.corners[c] = camera.Project(cam_from_world * corners[c]);
    set.tags.push_back(tag);
  }
  return set;
}

TargetConfig Targets() {
  TargetConfig t;
  t.size_m = kTagSize;
  return t;
}

Rigid3d ViewOf(int i) {
  const Eigen::Quaterniond r(Eigen::AngleAxisd(2.3 - 0.05 * i, Eigen::Vector3d::UnitX()) *
                             Eigen::AngleAxisd(0.04 * i, Eigen::Vector3d::UnitY()));
  const Eigen::Vector3d centre(0.03 * i, -0.6, 0.5);
  return Rigid3d(r, -(r * centre));
}

void ExpectReportRejectedOrRight(const FrameReport& report, const Rigid3d& truth, const std::string& what) {
  if (!report.registered) {
    EXPECT_FALSE(report.reason.empty()) << what << ": unregistered without a reason";
    return;
  }
  EXPECT_LT(RotationAngleDeg(report.cam_from_world.rotation, truth.rotation), 0.5) << what;
  EXPECT_LT((report.cam_from_world.Center() - truth.Center()).norm(), 0.01) << what;
}

TEST(DegenerateGeometry, SceneIsVisibleFromTheTestViews) {
  // Guards the tests below: every corner of every tag is in the image.
  const CameraModel camera = TestCamera();
  for (int i = 0; i < 6; ++i) {
    for (const auto& [id, corners] : SixTags()) {
      for (const auto& c : corners) {
        const Eigen::Vector3d p = ViewOf(i) * c;
        ASSERT_GT(p.z(), 0.1) << "view " << i << " tag " << id;
        const Eigen::Vector2d px = camera.Project(p);
        ASSERT_TRUE(px.x() > 0 && px.x() < 640 && px.y() > 0 && px.y() < 480) << "view " << i << " tag " << id;
      }
    }
  }
}

TEST(DegenerateGeometry, DuplicateTagIdsInOneFrameNeverGiveAWrongPose) {
  const TargetCornerMap map = SixTags();
  for (bool known : {true, false}) {
    auto recon = Reconstructor::Create(TestCamera(), Targets(), known ? std::optional(map) : std::nullopt, {});
    ASSERT_TRUE(recon.has_value()) << recon.error().message;
    for (int i = 0; i < 6; ++i) {
      DetectionSet set = Detect(i, ViewOf(i), map);
      // Tag 1 twice more: once 60 px off, once where tag 4 is.
      TagDetection moved = set.tags[1];
      for (auto& c : moved.corners) c += Eigen::Vector2d(60, -20);
      set.tags.push_back(moved);
      TagDetection swapped = set.tags[4];
      swapped.id = 1;
      set.tags.push_back(swapped);
      const FrameReport report = (*recon)->AddFrame(set);
      if (known) ExpectReportRejectedOrRight(report, ViewOf(i), "known map, frame " + std::to_string(i));
      if (!known && !report.registered) {
        EXPECT_FALSE(report.reason.empty()) << "frame " << i;
      }
    }
    const ReconstructionResult result = (*recon)->Finish();
    for (const auto& [frame, pose] : result.Poses()) {
      EXPECT_TRUE(pose.translation.allFinite() && pose.rotation.coeffs().allFinite()) << "frame " << frame;
      if (known) {
        EXPECT_LT(RotationAngleDeg(pose.rotation, ViewOf(frame).rotation), 0.5) << "frame " << frame;
        EXPECT_LT((pose.Center() - ViewOf(frame).Center()).norm(), 0.01) << "frame " << frame;
      }
    }
  }
}

TEST(DegenerateGeometry, NaNInfiniteAndHugeCornersNeverGiveAWrongPose) {
  const TargetCornerMap map = SixTags();
  auto recon = Reconstructor::Create(TestCamera(), Targets(), map, {});
  ASSERT_TRUE(recon.has_value()) << recon.error().message;
  const double values[] = {kNaN, kInf, -kInf, 1e300, -1e18};
  for (int i = 0; i < 5; ++i) {
    DetectionSet set = Detect(i, ViewOf(i), map);
    set.tags[2].corners[1].x() = values[i];
    set.tags[3].corners[3].y() = values[i];
    ExpectReportRejectedOrRight((*recon)->AddFrame(set), ViewOf(i), "value " + std::to_string(values[i]));
    (void)(*recon)->PredictTagCorners(i + 1);
  }
  // Every corner bad: no pose.
  DetectionSet all_bad = Detect(5, ViewOf(5), map);
  for (auto& tag : all_bad.tags) {
    for (auto& c : tag.corners) c = Eigen::Vector2d(kNaN, kInf);
  }
  const FrameReport report = (*recon)->AddFrame(all_bad);
  EXPECT_FALSE(report.registered);
  EXPECT_FALSE(report.reason.empty());
  const ReconstructionResult result = (*recon)->Finish();
  for (const auto& [frame, pose] : result.Poses()) {
    EXPECT_LT(RotationAngleDeg(pose.rotation, ViewOf(frame).rotation), 0.5) << "frame " << frame;
    EXPECT_LT((pose.Center() - ViewOf(frame).Center()).norm(), 0.01) << "frame " << frame;
  }
  EXPECT_TRUE(std::isfinite(result.reprojection_rms_px));
}

TEST(DegenerateGeometry, ZeroBaselineWithoutMapLeavesTagsUnmappedOrRight) {
  // The same view again and again: no angle between views, so a learned
  // map has nothing to decide its planar ambiguity or depth from. Tags may
  // be mapped only where they are (the first view starts the map after
  // bootstrap_max_frames), never somewhere wrong.
  const TargetCornerMap map = SixTags();
  auto recon = Reconstructor::Create(TestCamera(), Targets(), std::nullopt, {});
  ASSERT_TRUE(recon.has_value()) << recon.error().message;
  for (int i = 0; i < 14; ++i) {
    const FrameReport r = (*recon)->AddFrame(Detect(i, ViewOf(0), map));
    if (!r.registered) {
      EXPECT_FALSE(r.reason.empty()) << "frame " << i;
    }
  }
  const ReconstructionResult result = (*recon)->Finish();
  // The learned map is in the anchor tag's frame: compare the tags' shapes
  // through distances between tag centres, which do not depend on the frame.
  const TargetCornerMap learned = result.Targets();
  for (const auto& [a, ca] : learned) {
    for (const auto& [b, cb] : learned) {
      if (a >= b) continue;
      const double truth = (TagCenter(map.at(a)) - TagCenter(map.at(b))).norm();
      EXPECT_NEAR((TagCenter(ca) - TagCenter(cb)).norm(), truth, 0.01) << "tags " << a << ", " << b;
    }
  }
}

TEST(DegenerateGeometry, EmptyAndTinyFramesAreUnregisteredWithReason) {
  const TargetCornerMap map = SixTags();
  auto recon = Reconstructor::Create(TestCamera(), Targets(), map, {});
  ASSERT_TRUE(recon.has_value()) << recon.error().message;
  DetectionSet empty;
  empty.frame = 0;
  FrameReport r = (*recon)->AddFrame(empty);
  EXPECT_FALSE(r.registered);
  EXPECT_FALSE(r.reason.empty());
  // A tag of no map and zero size on the image (all four corners at one pixel).
  DetectionSet point;
  point.frame = 1;
  TagDetection tag;
  tag.id = 0;
  for (auto& c : tag.corners) c = Eigen::Vector2d(100, 100);
  point.tags.push_back(tag);
  r = (*recon)->AddFrame(point);
  EXPECT_FALSE(r.registered);
  EXPECT_FALSE(r.reason.empty());
  const ReconstructionResult result = (*recon)->Finish();
  EXPECT_TRUE(result.Poses().empty());
}

}  // namespace
}  // namespace tagsfm
