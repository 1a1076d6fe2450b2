// Degenerate geometry for the triangulation of feature points from known
// poses: no or one view, zero baseline, points behind the cameras, NaN and
// infinite input, huge coordinates. A point is dropped or right; never a
// crash, never a NaN or a wrong point in the cloud.
#include <cmath>
#include <limits>

#include <gtest/gtest.h>

#include "tagsfm/feature/feature_triangulation.h"
#include "tagsfm/feature/track_triangulation.h"

namespace tagsfm {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

CameraModel Camera() {
  CameraModel c;
  c.width = 640;
  c.height = 480;
  c.fx = c.fy = 500;
  c.cx = 319.5;
  c.cy = 239.5;
  return c;
}

// Cameras on a line 0.1 m apart, 1 m from the point, all looking along +z.
Rigid3d CameraAt(double x) { return Rigid3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(-x, 0, 0)); }

FeatureRay RayTo(const Rigid3d& cam_from_world, const Eigen::Vector3d& point) {
  return FeatureRay{cam_from_world, (cam_from_world * point).normalized()};
}

FeatureTrack TrackOf(const PoseMap& poses, const Eigen::Vector3d& point, TrackId id) {
  const CameraModel camera = Camera();
  FeatureTrack track;
  track.id = id;
  for (const auto& [frame, pose] : poses) {
    TrackObservation o;
    o.frame = frame;
    o.feature = static_cast<int>(id);
    o.pixel = camera.Project(pose * point);
    track.observations.push_back(o);
  }
  return track;
}

PoseMap FourCameras() {
  PoseMap poses;
  for (int i = 0; i < 4; ++i) poses[i] = CameraAt(0.1 * i);
  return poses;
}

// The property: every point given is finite, and within 1 mm of the truth
// (noise-free input; the refinement stops at ~1e-9 m).
void ExpectDroppedOrRight(const std::vector<FeaturePoint>& points, const Eigen::Vector3d& truth, const std::string& what) {
  for (const auto& p : points) {
    ASSERT_TRUE(p.position.allFinite()) << what;
    EXPECT_LT((p.position - truth).norm(), 1e-3) << what << ": point at " << p.position.transpose();
    EXPECT_TRUE(p.covariance.allFinite()) << what;
  }
}

TEST(DegenerateTriangulation, NoOrOneRayGivesNoPoint) {
  EXPECT_FALSE(TriangulateLinear({}).has_value());
  const Eigen::Vector3d point(0.1, 0.05, 1.0);
  EXPECT_FALSE(TriangulateLinear({RayTo(CameraAt(0), point)}).has_value());
}

TEST(DegenerateTriangulation, ZeroBaselineGivesNoPoint) {
  // Two, then five views from one place: parallel rays, depth undetermined.
  const Eigen::Vector3d point(0.1, 0.05, 1.0);
  const std::vector<FeatureRay> two(2, RayTo(CameraAt(0.2), point));
  EXPECT_FALSE(TriangulateLinear(two).has_value());
  PoseMap same;
  for (int i = 0; i < 5; ++i) same[i] = CameraAt(0.2);
  const auto points = TriangulateTracks({TrackOf(same, point, 1)}, same, Camera(), {});
  EXPECT_TRUE(points.empty()) << "a point from zero baseline";
}

TEST(DegenerateTriangulation, PointsBehindTheCamerasAreDropped) {
  // The views' pixels are those of a point behind every camera (z = -1):
  // rays meet behind the cameras, which no real point does.
  const PoseMap poses = FourCameras();
  const Eigen::Vector3d behind(0.1, 0.05, -1.0);
  FeatureTrack track;
  track.id = 3;
  for (const auto& [frame, pose] : poses) {
    const Eigen::Vector3d c = pose * behind;
    TrackObservation o;
    o.frame = frame;
    o.pixel = Eigen::Vector2d(500 * c.x() / c.z() + 319.5, 500 * c.y() / c.z() + 239.5);
    track.observations.push_back(o);
  }
  const auto points = TriangulateTracks({track}, poses, Camera(), {});
  for (const auto& p : points) {
    for (const auto& [frame, pose] : poses) EXPECT_GT((pose * p.position).z(), 0.0) << "point behind camera " << frame;
  }
  EXPECT_TRUE(points.empty());
}

TEST(DegenerateTriangulation, NaNAndInfiniteInputGiveNoWrongPoint) {
  const PoseMap poses = FourCameras();
  const Eigen::Vector3d truth(0.1, 0.05, 1.0);
  for (double bad : {kNaN, kInf, -kInf}) {
    const std::string what = "value " + std::to_string(bad);
    // One view's pixel bad (of four): dropped view, or dropped point.
    FeatureTrack track = TrackOf(poses, truth, 1);
    track.observations[2].pixel.x() = bad;
    ExpectDroppedOrRight(TriangulateTracks({track}, poses, Camera(), {}), truth, what + " in one pixel");
    // Every pixel bad.
    for (auto& o : track.observations) o.pixel = Eigen::Vector2d(bad, bad);
    EXPECT_TRUE(TriangulateTracks({track}, poses, Camera(), {}).empty()) << what << " in every pixel";
    // A pose with a bad translation.
    PoseMap bad_poses = poses;
    bad_poses[1].translation.x() = bad;
    ExpectDroppedOrRight(TriangulateTracks({TrackOf(poses, truth, 1)}, bad_poses, Camera(), {}), truth,
                         what + " in one pose");
    // Rays: a bad bearing makes the linear solution absent or finite.
    std::vector<FeatureRay> rays{RayTo(poses.at(0), truth), RayTo(poses.at(3), truth)};
    rays[1].bearing = Eigen::Vector3d(bad, 0, 1);
    const auto linear = TriangulateLinear(rays);
    if (linear) {
      EXPECT_TRUE(linear->allFinite()) << what << " in a bearing";
    }
  }
}

TEST(DegenerateTriangulation, HugeCoordinatesGiveNoWrongPoint) {
  const PoseMap poses = FourCameras();
  const Eigen::Vector3d truth(0.1, 0.05, 1.0);
  FeatureTrack track = TrackOf(poses, truth, 1);
  track.observations[1].pixel = Eigen::Vector2d(1e15, -1e15);
  ExpectDroppedOrRight(TriangulateTracks({track}, poses, Camera(), {}), truth, "a pixel at 1e15");
  // A point 1e9 m away: rays parallel to double precision; dropped (the
  // predicted sigma is far beyond max_relative_sigma) or right.
  const Eigen::Vector3d far(0, 0, 1e9);
  const auto points = TriangulateTracks({TrackOf(poses, far, 2)}, poses, Camera(), {});
  EXPECT_TRUE(points.empty()) << "a point 1e9 m away from a 0.3 m baseline";
}

// Every track given is counted once, under the first check it fails (or as a
// point): the counts say why a cloud is thin.
TEST(DegenerateTriangulation, EachTrackIsCountedUnderWhyItGaveNoPoint) {
  const Eigen::Vector3d point(0.1, 0.05, 1.0);
  PoseMap poses = FourCameras();   // frames 0-3, 0.1 m apart: 17 degrees
  poses[10] = CameraAt(0.0);
  poses[11] = CameraAt(0.001);     // 1 mm apart: 0.06 degrees
  poses[20] = poses[21] = CameraAt(0.2);  // one place: parallel rays
  const auto track_in = [&](std::vector<FrameId> frames, TrackId id) {
    PoseMap subset;
    for (FrameId f : frames) subset[f] = poses.count(f) ? poses.at(f) : CameraAt(0.3);
    return TrackOf(subset, point, id);
  };
  const FeatureTrack good = track_in({0, 1, 2, 3}, 1);
  const FeatureTrack one_posed = track_in({0, 99}, 2);  // frame 99 has no pose
  FeatureTrack one_far = track_in({0, 2}, 3);
  one_far.observations[1].pixel += Eigen::Vector2d(0, 10);  // across the epipolar line: dropped, leaving one view
  const FeatureTrack narrow = track_in({10, 11}, 4);
  const FeatureTrack parallel = track_in({20, 21}, 5);

  TrackTriangulationOptions options;
  options.max_relative_sigma = 1.0;  // the sigma check is tested on its own below
  TrackTriangulationStats stats;
  const auto points = TriangulateTracks({good, one_posed, one_far, narrow, parallel}, poses, Camera(), options, 2, &stats);
  ASSERT_EQ(points.size(), 1u);
  EXPECT_EQ(points[0].track, 1);
  EXPECT_EQ(stats.tracks, 5);
  EXPECT_EQ(stats.points, 1);
  EXPECT_EQ(stats.too_few_views, 2);
  EXPECT_EQ(stats.narrow_angle, 1);
  EXPECT_EQ(stats.no_linear_point, 1);
  EXPECT_EQ(stats.reprojection + stats.predicted_sigma, 0);

  // The same good track against a reprojection limit its 0.3 px of noise
  // exceeds, then against a sigma limit no point meets.
  FeatureTrack noisy = good;
  for (size_t i = 0; i < noisy.observations.size(); ++i) noisy.observations[i].pixel.y() += i % 2 ? 0.3 : -0.3;
  TrackTriangulationOptions strict = options;
  strict.max_reprojection_rms_px = 0.01;
  TrackTriangulationStats strict_stats;
  EXPECT_TRUE(TriangulateTracks({noisy}, poses, Camera(), strict, 1, &strict_stats).empty());
  EXPECT_EQ(strict_stats.reprojection, 1);
  strict = options;
  strict.max_relative_sigma = 1e-9;
  strict_stats += stats;  // counts add up over calls
  EXPECT_TRUE(TriangulateTracks({good}, poses, Camera(), strict, 1, &strict_stats).empty());
  EXPECT_EQ(strict_stats.predicted_sigma, 1);
  EXPECT_EQ(strict_stats.tracks, 7);
  EXPECT_EQ(strict_stats.points, 1);
}

}  // namespace
}  // namespace tagsfm
