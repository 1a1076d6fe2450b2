// Points refined one by one on held poses (the points the joint adjustment
// leaves out) against exact geometry: the exact point from exact views
// through a distorted lens, the least-squares point from noisy ones, an
// outlier view down-weighted by the Huber loss, and the same points for
// any number of threads.
#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "tagsfm/feature/held_pose_refinement.h"
#include "test_camera.h"

namespace tagsfm {
namespace {

CameraModel DistortedCamera() {
  CameraModel c = testing::PinholeCamera(1280, 720, 1000, 641.5, 358.0);
  c.distortion = {-0.05, 0.01, 0, 0, 0};
  return c;
}

// Cameras on an arc 2 m from the origin, looking at it, 8 degrees apart.
PoseMap ArcPoses(int count) {
  PoseMap poses;
  for (int i = 0; i < count; ++i) {
    const double a = (i - (count - 1) / 2.0) * 8.0 * M_PI / 180.0;
    const Eigen::Vector3d centre(2.0 * std::sin(a), 0.1, -2.0 * std::cos(a));
    const Eigen::Vector3d z = (-centre).normalized();
    const Eigen::Vector3d x = Eigen::Vector3d::UnitY().cross(z).normalized();
    Eigen::Matrix3d r;
    r.row(0) = x;
    r.row(1) = z.cross(x);
    r.row(2) = z;
    poses[10 * i] = Rigid3d(Eigen::Quaterniond(r), -(r * centre));
  }
  return poses;
}

FeaturePoint Observed(const PoseMap& poses, const CameraModel& camera, const Eigen::Vector3d& truth, double noise_px,
                      std::mt19937* rng) {
  std::normal_distribution<double> noise(0.0, noise_px);
  FeaturePoint p;
  p.position = truth;
  for (const auto& [frame, pose] : poses) {
    p.observations.emplace_back(frame, camera.Project(pose * truth) + Eigen::Vector2d(noise(*rng), noise(*rng)));
  }
  return p;
}

// Sum of squared pixel residuals, through the lens as the refinement sees them.
double SumOfSquares(const PoseMap& poses, const CameraModel& camera, const FeaturePoint& p, const Eigen::Vector3d& x) {
  double sum = 0;
  for (const auto& [frame, pixel] : p.observations) {
    const Eigen::Vector3d in_cam = poses.at(frame) * x;
    const Eigen::Vector2d n = camera.PixelToNormalized(pixel);
    sum += Eigen::Vector2d(camera.fx * (in_cam.x() / in_cam.z() - n.x()), camera.fy * (in_cam.y() / in_cam.z() - n.y()))
               .squaredNorm();
  }
  return sum;
}

TEST(HeldPoseRefinement, ExactViewsThroughADistortedLensGiveTheExactPoint) {
  const CameraModel camera = DistortedCamera();
  const PoseMap poses = ArcPoses(4);
  std::mt19937 rng(1);
  const Eigen::Vector3d truth(0.3, -0.2, 0.25);
  std::vector<FeaturePoint> points = {Observed(poses, camera, truth, 0.0, &rng)};
  points[0].position = truth + Eigen::Vector3d(0.02, -0.01, 0.03);  // 3.7 cm off
  RefinePointsOnHeldPoses(poses, camera, {}, {0}, &points);
  // The lens is inverted iteratively (PixelToNormalized): ~1e-10 of the image.
  EXPECT_LT((points[0].position - truth).norm(), 1e-8);
}

// With a Huber scale far above the noise the minimum is the least-squares
// one: no step along any axis lowers the sum of squares.
TEST(HeldPoseRefinement, NoisyViewsGiveTheLeastSquaresPoint) {
  const CameraModel camera = DistortedCamera();
  const PoseMap poses = ArcPoses(5);
  std::mt19937 rng(2);
  HeldPoseRefinementOptions options;
  options.huber_px = 1e6;
  for (int trial = 0; trial < 20; ++trial) {
    std::uniform_real_distribution<double> at(-0.4, 0.4);
    const Eigen::Vector3d truth(at(rng), at(rng), at(rng));
    std::vector<FeaturePoint> points = {Observed(poses, camera, truth, 0.5, &rng)};
    RefinePointsOnHeldPoses(poses, camera, options, {0}, &points);
    const Eigen::Vector3d x = points[0].position;
    const double at_minimum = SumOfSquares(poses, camera, points[0], x);
    for (int axis = 0; axis < 3; ++axis) {
      for (double step : {-1e-6, 1e-6}) {
        EXPECT_GE(SumOfSquares(poses, camera, points[0], x + step * Eigen::Vector3d::Unit(axis)), at_minimum - 1e-12)
            << "trial " << trial << " axis " << axis;
      }
    }
    // 0.5 px at 2 m is 0.5 mm across a ray; along the rays, seen over 32
    // degrees, ~1.6 mm (1 sigma) over five views: 1 cm is beyond 5 sigma.
    EXPECT_LT((x - truth).norm(), 1e-2) << "trial " << trial;
  }
}

// One of six views 20 px off: the Huber loss (1 px) gives it the weight of
// a 1 px error, least squares lets it pull the point.
TEST(HeldPoseRefinement, AnOutlierViewIsDownWeighted) {
  const CameraModel camera = DistortedCamera();
  const PoseMap poses = ArcPoses(6);
  std::mt19937 rng(3);
  const Eigen::Vector3d truth(0.1, 0.2, -0.1);
  FeaturePoint observed = Observed(poses, camera, truth, 0.05, &rng);
  observed.observations[2].second += Eigen::Vector2d(20.0, -5.0);
  HeldPoseRefinementOptions robust, plain;
  plain.huber_px = 1e6;
  std::vector<FeaturePoint> a = {observed}, b = {observed};
  RefinePointsOnHeldPoses(poses, camera, robust, {0}, &a);
  RefinePointsOnHeldPoses(poses, camera, plain, {0}, &b);
  const double robust_mm = 1e3 * (a[0].position - truth).norm(), plain_mm = 1e3 * (b[0].position - truth).norm();
  std::printf("outlier view: %.3f mm with the Huber loss, %.3f mm without\n", robust_mm, plain_mm);
  EXPECT_LT(robust_mm, 0.25 * plain_mm);
  EXPECT_GT(plain_mm, 1.0);
}

TEST(HeldPoseRefinement, APointBehindACameraKeepsItsPosition) {
  const CameraModel camera = DistortedCamera();
  PoseMap poses = ArcPoses(3);
  std::mt19937 rng(4);
  std::vector<FeaturePoint> points = {Observed(poses, camera, Eigen::Vector3d(0.1, 0, 0), 0.0, &rng)};
  const Eigen::Vector3d start = Eigen::Vector3d(0, 0, -3.0);  // behind every camera (they sit at z ~ -2)
  points[0].position = start;
  RefinePointsOnHeldPoses(poses, camera, {}, {0}, &points);
  EXPECT_EQ(points[0].position, start);
}

TEST(HeldPoseRefinement, AnyNumberOfThreadsGivesTheSamePoints) {
  const CameraModel camera = DistortedCamera();
  const PoseMap poses = ArcPoses(5);
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> at(-0.4, 0.4);
  std::vector<FeaturePoint> points;
  std::vector<size_t> which;
  for (int i = 0; i < 700; ++i) {
    const Eigen::Vector3d truth(at(rng), at(rng), at(rng));
    points.push_back(Observed(poses, camera, truth, 0.3, &rng));
    points.back().position = truth + Eigen::Vector3d(at(rng), at(rng), at(rng)) * 0.01;
    if (i % 3 != 0) which.push_back(static_cast<size_t>(i));  // the others are not to be touched
  }
  std::vector<FeaturePoint> one = points, three = points;
  HeldPoseRefinementOptions options;
  options.threads = 1;
  RefinePointsOnHeldPoses(poses, camera, options, which, &one);
  options.threads = 3;
  RefinePointsOnHeldPoses(poses, camera, options, which, &three);
  for (size_t i = 0; i < points.size(); ++i) {
    EXPECT_EQ(one[i].position, three[i].position) << i;
    if (i % 3 == 0) {
      EXPECT_EQ(one[i].position, points[i].position) << i;
    } else {
      EXPECT_NE(one[i].position, points[i].position) << i;
    }
  }
}

}  // namespace
}  // namespace tagsfm
