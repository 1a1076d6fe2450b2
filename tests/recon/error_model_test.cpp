// The error model against Monte-Carlo runs (within 20%, the bar) and
// against its own analytic properties (error proportional to depth and noise).
#include "tagsfm/recon/error_model.h"

#include <cmath>
#include <cstdio>
#include <numbers>
#include <random>
#include <vector>

#include <gtest/gtest.h>
#include <Eigen/Geometry>
#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>

#include "tagsfm/core/rigid3d.h"

namespace tagsfm {
namespace {

constexpr double kDegToRad = std::numbers::pi / 180.0;
// Monte-Carlo RMS values from a few hundred trials scatter by about
// 1/sqrt(2 trials) ~ 3-5%; the model is first order, so 20% (the bar)
// leaves room for both without letting a wrong factor (sqrt 2, 2) through.
constexpr double kModelTolerance = 0.20;

double Rms(const std::vector<double>& values) {
  double sum = 0;
  for (double v : values) sum += v * v;
  return std::sqrt(sum / values.size());
}

// Pixel (relative to the principal point) of a point in the camera frame.
Eigen::Vector2d ProjectCentered(const Eigen::Vector3d& p, double focal_px) { return focal_px * p.head<2>() / p.z(); }

// The paper's section 4.1.1: the noisy pixel's ray, at the true distance.
TEST(ErrorModel, PointAlongRayMatchesMonteCarlo) {
  std::mt19937 rng(1);
  const double focal_px = 800;
  for (double depth : {2.0, 10.0, 30.0}) {
    for (double sigma : {0.5, 3.0}) {
      std::normal_distribution<double> noise(0.0, sigma);
      std::vector<double> errors;
      const Eigen::Vector3d point(0.05 * depth, -0.03 * depth, depth);  // near the axis, as the model assumes
      for (int trial = 0; trial < 2000; ++trial) {
        const Eigen::Vector2d pixel = ProjectCentered(point, focal_px) + Eigen::Vector2d(noise(rng), noise(rng));
        const Eigen::Vector3d ray = Eigen::Vector3d(pixel.x() / focal_px, pixel.y() / focal_px, 1.0).normalized();
        errors.push_back((ray * point.norm() - point).norm());
      }
      EXPECT_NEAR(Rms(errors), PointErrorAlongRayRms(depth, focal_px, sigma),
                  kModelTolerance * PointErrorAlongRayRms(depth, focal_px, sigma))
          << "depth " << depth << " sigma " << sigma;
    }
  }
}

TEST(ErrorModel, PointErrorIsProportionalToDepthAndNoise) {
  const double base = PointErrorAlongRayRms(2.0, 1000, 1.0);
  EXPECT_NEAR(PointErrorAlongRayRms(20.0, 1000, 1.0), 10 * base, 1e-12);
  EXPECT_NEAR(PointErrorAlongRayRms(2.0, 1000, 3.0), 3 * base, 1e-12);
  EXPECT_EQ(PointErrorAlongRayRms(2.0, 1000, 0.0), 0.0);
  const double tri = TriangulatedPointErrorRms(5.0, 1000, 1.0, 10 * kDegToRad);
  EXPECT_NEAR(TriangulatedPointErrorRms(10.0, 1000, 1.0, 10 * kDegToRad), 2 * tri, 1e-12);
  EXPECT_NEAR(TriangulatedPointErrorRms(5.0, 1000, 2.0, 10 * kDegToRad), 2 * tri, 1e-12);
  // Halving a small baseline angle about doubles the (depth-dominated) error.
  EXPECT_NEAR(TriangulatedPointErrorRms(5.0, 1000, 1.0, 5 * kDegToRad) / tri, 2.0, 0.05);
}

// Two cameras at `depth` from the point, rays meeting at `angle`; the point is
// triangulated by least squares on the ray distances.
double TriangulationMonteCarloRms(double depth, double focal_px, double sigma, double angle, std::mt19937& rng) {
  std::normal_distribution<double> noise(0.0, sigma);
  const Eigen::Vector3d point(0.1, -0.2, 0.3);
  std::vector<Eigen::Vector3d> centres;
  std::vector<Eigen::Matrix3d> world_from_cam;
  for (double side : {-0.5, 0.5}) {
    const Eigen::Matrix3d r = Eigen::AngleAxisd(side * angle, Eigen::Vector3d::UnitY()).toRotationMatrix();
    world_from_cam.push_back(r);
    centres.push_back(point - depth * r.col(2));  // the camera looks along its +z at the point
  }
  std::vector<double> errors;
  for (int trial = 0; trial < 1500; ++trial) {
    Eigen::Matrix3d normal = Eigen::Matrix3d::Zero();
    Eigen::Vector3d rhs = Eigen::Vector3d::Zero();
    for (size_t c = 0; c < centres.size(); ++c) {
      const Eigen::Vector3d in_cam = world_from_cam[c].transpose() * (point - centres[c]);
      const Eigen::Vector2d pixel = ProjectCentered(in_cam, focal_px) + Eigen::Vector2d(noise(rng), noise(rng));
      const Eigen::Vector3d ray = (world_from_cam[c] * Eigen::Vector3d(pixel.x() / focal_px, pixel.y() / focal_px, 1)).normalized();
      const Eigen::Matrix3d perp = Eigen::Matrix3d::Identity() - ray * ray.transpose();
      normal += perp;
      rhs += perp * centres[c];
    }
    errors.push_back((normal.ldlt().solve(rhs) - point).norm());
  }
  return Rms(errors);
}

TEST(ErrorModel, TriangulatedPointMatchesMonteCarlo) {
  std::mt19937 rng(2);
  const double focal_px = 1000;
  for (double depth : {2.0, 10.0}) {
    for (double angle_deg : {5.0, 20.0, 60.0}) {
      const double sigma = 1.0;
      const double angle = angle_deg * kDegToRad;
      const double model = TriangulatedPointErrorRms(depth, focal_px, sigma, angle);
      EXPECT_NEAR(TriangulationMonteCarloRms(depth, focal_px, sigma, angle, rng), model, kModelTolerance * model)
          << "depth " << depth << " angle " << angle_deg;
      // The general ray model agrees with the two-view formula.
      std::vector<RayObservation> rays;
      for (double side : {-0.5, 0.5}) {
        rays.push_back({Eigen::Vector3d(std::sin(side * angle), 0, std::cos(side * angle)), depth, sigma / focal_px});
      }
      Result<Eigen::Matrix3d> covariance = TriangulatedPointCovariance(rays);
      ASSERT_TRUE(covariance.has_value());
      EXPECT_NEAR(std::sqrt(covariance->trace()), model, 1e-6 * model);
    }
  }
}

TEST(ErrorModel, TriangulationRejectsParallelRays) {
  const std::vector<RayObservation> rays = {{Eigen::Vector3d::UnitZ(), 5, 0.001}, {Eigen::Vector3d::UnitZ(), 6, 0.001}};
  EXPECT_FALSE(TriangulatedPointCovariance(rays).has_value());
  EXPECT_FALSE(TriangulatedPointCovariance({rays[0]}).has_value());
}

struct PoseMonteCarlo {
  double rotation_deg_rms = 0;
  double position_rms = 0;
};

// EPnP followed by Levenberg-Marquardt (the maximum-likelihood estimate the
// model describes). The true pose is the identity: errors are |rvec| and |t|.
// `new_points` draws each trial's targets (and may redraw them per trial).
template <class DrawPoints>
PoseMonteCarlo SolvePoseMonteCarlo(int trials, double focal_px, double sigma_px, double target_noise,
                                   DrawPoints new_points, std::mt19937& rng) {
  std::normal_distribution<double> pixel_noise(0.0, sigma_px);
  std::normal_distribution<double> point_noise(0.0, target_noise);
  const cv::Matx33d k(focal_px, 0, 0, 0, focal_px, 0, 0, 0, 1);
  std::vector<double> rotation_deg, position;
  for (int trial = 0; trial < trials; ++trial) {
    const std::vector<Eigen::Vector3d> points = new_points();
    std::vector<cv::Point3d> object;
    std::vector<cv::Point2d> image;
    for (const Eigen::Vector3d& p : points) {
      const Eigen::Vector2d pixel = ProjectCentered(p, focal_px);
      image.emplace_back(pixel.x() + pixel_noise(rng), pixel.y() + pixel_noise(rng));
      object.emplace_back(p.x() + point_noise(rng), p.y() + point_noise(rng), p.z() + point_noise(rng));
    }
    cv::Mat rvec, tvec;
    cv::solvePnP(object, image, k, cv::noArray(), rvec, tvec, false, cv::SOLVEPNP_EPNP);
    cv::solvePnPRefineLM(object, image, k, cv::noArray(), rvec, tvec);
    rotation_deg.push_back(cv::norm(rvec) / kDegToRad);
    position.push_back(cv::norm(tvec));  // centre = -R^T t, |centre| = |t|
  }
  return {Rms(rotation_deg), Rms(position)};
}

// Targets uniform on a disc of RMS radius spread_px in the image, depths
// uniform with RMS relief: the distribution the summary model describes.
std::vector<Eigen::Vector3d> RandomView(const ViewConditions& view, std::mt19937& rng) {
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  const double disc_radius = view.spread_px * std::sqrt(2.0);
  std::vector<Eigen::Vector3d> points;
  for (int i = 0; i < view.num_targets; ++i) {
    const double r = disc_radius * std::sqrt(unit(rng));
    const double a = 2 * std::numbers::pi * unit(rng);
    const double z = view.depth_m * (1 + view.depth_relief * std::sqrt(3.0) * (2 * unit(rng) - 1));
    points.emplace_back(r * std::cos(a) / view.focal_px * z, r * std::sin(a) / view.focal_px * z, z);
  }
  return points;
}

void ExpectWithinModelTolerance(double monte_carlo, double model, const char* what, const ViewConditions& view) {
  std::printf("  %-8s n=%3d sigma=%.1fpx target_noise=%.3fm: model %.4g, Monte-Carlo %.4g (%+.1f%%)\n", what,
              view.num_targets, view.image_noise_px, view.target_noise_m, model, monte_carlo,
              100.0 * (monte_carlo / model - 1.0));
  EXPECT_NEAR(monte_carlo, model, kModelTolerance * model)
      << what << ": n " << view.num_targets << " sigma " << view.image_noise_px << " px, target noise "
      << view.target_noise_m << " m, spread " << view.spread_px << " px, relief " << view.depth_relief
      << ", depth " << view.depth_m;
}

TEST(ErrorModel, PoseCovarianceMatchesMonteCarloForFixedTargets) {
  std::mt19937 rng(3);
  for (int n : {8, 40}) {
    ViewConditions view;
    view.num_targets = n;
    view.image_noise_px = 1.0;
    view.depth_relief = 0.2;
    view.spread_px = 250;
    const std::vector<Eigen::Vector3d> targets = RandomView(view, rng);
    const Result<Eigen::Matrix<double, 6, 6>> covariance =
        PoseCovariance(targets, view.focal_px, std::vector<double>(targets.size(), view.image_noise_px));
    ASSERT_TRUE(covariance.has_value()) << covariance.error().message;
    const PoseErrorRms model = PoseErrorFromCovariance(*covariance);
    const PoseMonteCarlo mc = SolvePoseMonteCarlo(400, view.focal_px, view.image_noise_px, 0.0, [&] { return targets; }, rng);
    ExpectWithinModelTolerance(mc.rotation_deg_rms, model.rotation_deg, "rotation", view);
    ExpectWithinModelTolerance(mc.position_rms, model.position_m, "position", view);
  }
}

// The summary model (depth, noise, count, spread, relief) against random
// views with those statistics, over a range of conditions.
TEST(ErrorModel, PredictPoseErrorMatchesMonteCarloOverConditions) {
  std::mt19937 rng(4);
  struct Case {
    int n;
    double sigma_px, target_noise_m, spread_px, relief, depth_m;
  };
  const Case cases[] = {
      {20, 0.5, 0.0, 200, 0.1, 5},   {20, 2.0, 0.0, 300, 0.2, 10},  {50, 1.0, 0.0, 150, 0.3, 3},
      {100, 5.0, 0.0, 250, 0.1, 8},  {50, 0.0, 0.005, 200, 0.2, 5}, {30, 0.5, 0.01, 300, 0.15, 4},
  };
  for (const Case& c : cases) {
    ViewConditions view;
    view.num_targets = c.n;
    view.image_noise_px = c.sigma_px;
    view.target_noise_m = c.target_noise_m;
    view.spread_px = c.spread_px;
    view.depth_relief = c.relief;
    view.depth_m = c.depth_m;
    const Result<PoseErrorRms> model = PredictPoseError(view);
    ASSERT_TRUE(model.has_value()) << model.error().message;
    const PoseMonteCarlo mc = SolvePoseMonteCarlo(
        300, view.focal_px, view.image_noise_px, view.target_noise_m, [&] { return RandomView(view, rng); }, rng);
    ExpectWithinModelTolerance(mc.rotation_deg_rms, model->rotation_deg, "rotation", view);
    ExpectWithinModelTolerance(mc.position_rms, model->position_m, "position", view);
  }
}

TEST(ErrorModel, PoseErrorScalesWithNoiseAndCount) {
  ViewConditions view;
  view.num_targets = 40;
  view.image_noise_px = 1.0;
  const PoseErrorRms base = *PredictPoseError(view);
  view.image_noise_px = 3.0;
  const PoseErrorRms noisier = *PredictPoseError(view);
  EXPECT_NEAR(noisier.rotation_deg, 3 * base.rotation_deg, 1e-9 * base.rotation_deg);
  EXPECT_NEAR(noisier.position_m, 3 * base.position_m, 1e-9 * base.position_m);
  view.image_noise_px = 1.0;
  view.num_targets = 160;  // 4x the targets: about half the error (1/sqrt n; the patterns differ slightly)
  const PoseErrorRms more = *PredictPoseError(view);
  EXPECT_NEAR(more.position_m / base.position_m, 0.5, 0.05);
  EXPECT_NEAR(more.rotation_deg / base.rotation_deg, 0.5, 0.05);
  view.image_noise_px = 0;
  EXPECT_EQ(PredictPoseError(view)->position_m, 0.0);
}

// Feature point from two views whose poses come from n noisy targets each.
TEST(ErrorModel, FeaturePointWithPoseUncertaintyMatchesMonteCarlo) {
  std::mt19937 rng(5);
  ViewConditions view;
  view.num_targets = 8;  // few targets: the pose term (3/n) is a visible part of the error
  view.image_noise_px = 2.0;
  view.spread_px = 250;
  view.depth_relief = 0.2;
  view.depth_m = 5;
  const double angle = 20 * kDegToRad;
  std::normal_distribution<double> noise(0.0, view.image_noise_px);
  const cv::Matx33d k(view.focal_px, 0, 0, 0, view.focal_px, 0, 0, 0, 1);
  std::uniform_int_distribution<int> pick(0, view.num_targets - 1);
  std::vector<double> errors;
  for (int trial = 0; trial < 600; ++trial) {
    // Targets in the world frame of camera 0; camera 1 sees them rotated by `angle` about the feature.
    const std::vector<Eigen::Vector3d> targets = RandomView(view, rng);
    const Eigen::Vector3d feature = targets[pick(rng)] + Eigen::Vector3d(0.01, 0.02, 0.0);  // a point among the targets
    const Eigen::Matrix3d turn = Eigen::AngleAxisd(angle, Eigen::Vector3d::UnitY()).toRotationMatrix();
    const Rigid3d cams_from_world[2] = {Rigid3d(), Rigid3d(Eigen::Quaterniond(turn), feature - turn * feature)};
    Eigen::Matrix3d normal = Eigen::Matrix3d::Zero();
    Eigen::Vector3d rhs = Eigen::Vector3d::Zero();
    for (const Rigid3d& cam_from_world : cams_from_world) {
      std::vector<cv::Point3d> object;
      std::vector<cv::Point2d> image;
      for (const Eigen::Vector3d& t : targets) {
        const Eigen::Vector2d px = ProjectCentered(cam_from_world * t, view.focal_px);
        object.emplace_back(t.x(), t.y(), t.z());
        image.emplace_back(px.x() + noise(rng), px.y() + noise(rng));
      }
      cv::Mat rvec, tvec;
      cv::solvePnP(object, image, k, cv::noArray(), rvec, tvec, false, cv::SOLVEPNP_EPNP);
      cv::solvePnPRefineLM(object, image, k, cv::noArray(), rvec, tvec);
      cv::Matx33d r_cv;
      cv::Rodrigues(rvec, r_cv);
      Eigen::Matrix3d cam_rotation;
      cv::cv2eigen(r_cv, cam_rotation);
      const Eigen::Vector3d t_est(tvec.at<double>(0), tvec.at<double>(1), tvec.at<double>(2));
      const Eigen::Vector3d centre = -cam_rotation.transpose() * t_est;
      const Eigen::Vector2d px = ProjectCentered(cam_from_world * feature, view.focal_px) + Eigen::Vector2d(noise(rng), noise(rng));
      const Eigen::Vector3d ray = (cam_rotation.transpose() * Eigen::Vector3d(px.x() / view.focal_px, px.y() / view.focal_px, 1)).normalized();
      const Eigen::Matrix3d perp = Eigen::Matrix3d::Identity() - ray * ray.transpose();
      normal += perp;
      rhs += perp * centre;
    }
    errors.push_back((normal.ldlt().solve(rhs) - feature).norm());
  }
  // The feature's depth varies with the random targets; the model takes the mean depth.
  const Result<double> model = PredictFeaturePointErrorRms(view, angle);
  ASSERT_TRUE(model.has_value());
  std::printf("  feature point: model %.4g m, Monte-Carlo %.4g m (%+.1f%%)\n", *model, Rms(errors),
              100.0 * (Rms(errors) / *model - 1.0));
  EXPECT_NEAR(Rms(errors), *model, kModelTolerance * *model);
  // Without the pose term the model would be clearly lower than the simulation.
  EXPECT_LT(TriangulatedPointErrorRms(view.depth_m, view.focal_px, view.image_noise_px, angle), 0.9 * Rms(errors));
}

TEST(ErrorModel, MaxDepthForPointErrorMeetsTheGoalExactly) {
  ViewConditions view;
  view.image_noise_px = 1.0;
  view.num_targets = 30;
  const double angle = 15 * kDegToRad;
  const Result<double> depth = MaxDepthForPointError(0.002, view, angle);
  ASSERT_TRUE(depth.has_value());
  view.depth_m = *depth;
  EXPECT_NEAR(*PredictFeaturePointErrorRms(view, angle), 0.002, 1e-9);
  // Twice the noise: half the depth (error proportional to depth * sigma).
  view.image_noise_px = 2.0;
  EXPECT_NEAR(*MaxDepthForPointError(0.002, view, angle), 0.5 * *depth, 1e-9 * *depth);
  // Target noise adds a depth-independent floor k * noise * sqrt(3/n) (k ~ 5.5
  // at 15 degrees): 0.5 mm leaves the 2 mm goal reachable, closer; 1 cm does not.
  view.image_noise_px = 1.0;
  view.target_noise_m = 0.0005;
  const Result<double> with_floor = MaxDepthForPointError(0.002, view, angle);
  ASSERT_TRUE(with_floor.has_value());
  EXPECT_GT(*with_floor, 0.0);
  EXPECT_LT(*with_floor, *depth);
  view.depth_m = *with_floor;
  EXPECT_NEAR(*PredictFeaturePointErrorRms(view, angle), 0.002, 1e-9);
  view.target_noise_m = 0.01;
  EXPECT_EQ(*MaxDepthForPointError(0.002, view, angle), 0.0);
}

TEST(ErrorModel, MaxDepthForPoseErrorMeetsTheGoal) {
  ViewConditions view;
  view.image_noise_px = 1.0;
  view.num_targets = 30;
  view.depth_m = 4;
  view.depth_relief = 0.1;
  const double radius_m = 1.0;
  const Result<std::optional<double>> depth = MaxDepthForPoseError(0.005, view, radius_m);
  ASSERT_TRUE(depth.has_value() && depth->has_value());
  ViewConditions at = view;
  at.depth_m = **depth;
  at.spread_px = view.focal_px * radius_m / at.depth_m;
  at.depth_relief = view.depth_relief * view.depth_m / at.depth_m;
  EXPECT_NEAR(PredictPoseError(at)->position_m, 0.005, 1e-4);
  // A tighter goal asks to come closer.
  EXPECT_LT(**MaxDepthForPoseError(0.002, view, radius_m), **depth);
  EXPECT_FALSE(MaxDepthForPoseError(-1, view, radius_m).has_value());
}

TEST(ErrorModel, TargetsNeededIsTheSmallestCountMeetingTheGoal) {
  ViewConditions view;
  view.image_noise_px = 1.0;
  view.spread_px = 200;
  const Result<std::optional<int>> needed = TargetsNeeded(0.05, 0.01, view);
  ASSERT_TRUE(needed.has_value() && needed->has_value());
  const int n = **needed;
  view.num_targets = n;
  const PoseErrorRms at_n = *PredictPoseError(view);
  EXPECT_TRUE(at_n.rotation_deg <= 0.05 && at_n.position_m <= 0.01);
  view.num_targets = n - 1;
  const PoseErrorRms below = *PredictPoseError(view);
  EXPECT_TRUE(below.rotation_deg > 0.05 || below.position_m > 0.01);
  // Error ~ sigma / sqrt(n): three times the noise needs about nine times the targets.
  view.image_noise_px = 3.0;
  const int n_noisy = **TargetsNeeded(0.05, 0.01, view);
  EXPECT_NEAR(static_cast<double>(n_noisy) / n, 9.0, 1.5);
  // Unreachable within the cap.
  EXPECT_FALSE(TargetsNeeded(1e-6, 1e-6, view, 500)->has_value());
}

TEST(ErrorModel, RejectsBadConditionsNamingTheField) {
  ViewConditions view;
  view.depth_m = -1;
  ASSERT_FALSE(PredictPoseError(view).has_value());
  EXPECT_NE(PredictPoseError(view).error().message.find("depth_m"), std::string::npos);
  view = ViewConditions();
  view.num_targets = 2;
  EXPECT_NE(view.Check().error().message.find("num_targets"), std::string::npos);
  view = ViewConditions();
  view.depth_relief = 0.9;
  EXPECT_NE(view.Check().error().message.find("depth_relief"), std::string::npos);
  view = ViewConditions();
  view.spread_px = 0;
  EXPECT_FALSE(PredictFeaturePointErrorRms(view, 0.1).has_value());
  EXPECT_FALSE(PredictFeaturePointErrorRms(ViewConditions(), 0.0).has_value());
  // Collinear targets do not fix the roll about their line.
  std::vector<Eigen::Vector3d> line;
  for (int i = 0; i < 10; ++i) line.emplace_back(0.1 * i, 0, 5);
  EXPECT_FALSE(PoseCovariance(line, 1000, std::vector<double>(10, 1.0)).has_value());
}

}  // namespace
}  // namespace tagsfm
