// Section 4.1: the 1x1x1 box with 100 points and a camera moved along Z.
#include <cmath>

#include "experiment_common.h"
#include "tagsfm/analysis/experiments.h"
#include "tagsfm/analysis/pose_solvers.h"

namespace tagsfm::analysis {
namespace {

constexpr int kBoxPoints = 100;
constexpr double kBoxEdge = 1.0;

// Camera depths 2, 4, ..., 30: distance from the camera centre to the box centre.
std::vector<double> Depths() {
  std::vector<double> depths;
  for (int d = 2; d <= 30; d += 2) depths.push_back(d);
  return depths;
}

// A camera on the -Z axis looking along +Z at the box centre.
Rigid3d CameraAtDepth(double depth) { return Rigid3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0, 0, depth)); }

ExperimentResult DepthResultFrame(const std::string& name, const ExperimentOptions& options) {
  ExperimentResult result;
  result.name = name;
  result.x_column = "depth_units";
  result.x_label = "camera depth (units; box edge = 1)";
  result.trials = options.trials;
  result.notes.push_back("camera: 1280x960 px, focal 1000 px, on the -Z axis looking at the box centre; depth is "
                         "the distance to the box centre (the near face is 0.5 closer)");
  return result;
}

}  // namespace

ExperimentResult RunDepthImageNoise(const ExperimentOptions& options) {
  ExperimentResult result = DepthResultFrame("depth-image-noise", options);
  result.title = "Camera depth vs 3D error of a point on a noisy ray (paper 4.1.1, fig. 2)";
  result.series_column = "image_noise_px";
  result.series_legend = "σ = %s px";
  Grid grid;
  grid.xs = Depths();
  for (int sigma = 0; sigma <= 5; ++sigma) grid.series.push_back(FormatValue(sigma));
  const CameraModel camera = ExperimentCamera();
  const Accumulator values = ParallelSweep(options.trials, grid.Conditions(), 1, options.threads, [&](int trial, Accumulator& out) {
    std::mt19937 rng(ItemSeed(options.seed, 1, trial));
    const std::vector<SurfacePoint> box = BoxSurfacePoints(kBoxPoints, kBoxEdge, rng);
    std::normal_distribution<double> unit_noise(0.0, 1.0);
    for (size_t d = 0; d < grid.xs.size(); ++d) {
      const Rigid3d cam_from_world = CameraAtDepth(grid.xs[d]);
      for (size_t s = 0; s < grid.series.size(); ++s) {
        const double sigma = static_cast<double>(s);
        for (const SurfacePoint& point : box) {
          // The paper's procedure: the noisy pixel's unit ray, out to the true distance.
          const Eigen::Vector3d in_cam = cam_from_world * point.position;
          const Eigen::Vector2d pixel =
              ProjectToPixel(camera, in_cam) + sigma * Eigen::Vector2d(unit_noise(rng), unit_noise(rng));
          const Eigen::Vector3d ray =
              Eigen::Vector3d((pixel.x() - camera.cx) / camera.fx, (pixel.y() - camera.cy) / camera.fy, 1.0).normalized();
          out.Add(grid.Index(0, static_cast<int>(s), static_cast<int>(d)), 0,
                  PositionalError(ray * in_cam.norm(), in_cam));
        }
      }
    }
  });
  AddRows(result, "box", grid, {kPositionalError}, values);
  result.panels = {{"box", "", kPositionalError, Statistic::kMean, "positional error (units)", false},
                   {"box", "", kPositionalError, Statistic::kStd, "std of positional error (units)", false}};
  result.notes.push_back("each trial: a new set of 100 points on the box surface, new noise; values over all points of all trials");
  return result;
}

ExperimentResult RunDepthPointNoise(const ExperimentOptions& options) {
  ExperimentResult result = DepthResultFrame("depth-point-noise", options);
  result.title = "Camera depth vs EPnP pose from noisy 3D points (paper 4.1.2, fig. 3)";
  result.series_column = "point_noise_units";
  result.series_legend = "σ = %s";
  Grid grid;
  grid.xs = Depths();
  for (int tenth = 0; tenth <= 10; ++tenth) grid.series.push_back(FormatValue(tenth / 10.0));
  const CameraModel camera = ExperimentCamera();
  const Accumulator values = ParallelSweep(options.trials, grid.Conditions(), 4, options.threads, [&](int trial, Accumulator& out) {
    std::mt19937 rng(ItemSeed(options.seed, 2, trial));
    const std::vector<SurfacePoint> box = BoxSurfacePoints(kBoxPoints, kBoxEdge, rng);
    std::normal_distribution<double> unit_noise(0.0, 1.0);
    for (size_t d = 0; d < grid.xs.size(); ++d) {
      const Rigid3d cam_from_world = CameraAtDepth(grid.xs[d]);
      std::vector<Eigen::Vector2d> true_pixels;  // fixed: the 2D projections are exact
      for (const SurfacePoint& point : box) true_pixels.push_back(ProjectToPixel(camera, cam_from_world * point.position));
      for (size_t s = 0; s < grid.series.size(); ++s) {
        const double sigma = s / 10.0;
        std::vector<Eigen::Vector3d> noisy_points;
        for (const SurfacePoint& point : box) {
          Eigen::Vector3d noisy;
          do {  // as in the paper, every noisy point stays in front of the camera
            noisy = point.position + sigma * Eigen::Vector3d(unit_noise(rng), unit_noise(rng), unit_noise(rng));
          } while ((cam_from_world * noisy).z() < 0.1);
          noisy_points.push_back(noisy);
        }
        const SolvedPose pose = SolvePose(PoseSolver::kEpnp, noisy_points, true_pixels, camera);
        if (!pose.ok) continue;
        AddPoseMetrics(out, grid.Index(0, static_cast<int>(s), static_cast<int>(d)), pose.cam_from_world,
                       cam_from_world, noisy_points, true_pixels, camera);
      }
    }
  });
  AddRows(result, "box", grid, PoseMetrics(), values);
  result.panels = {{"box", "", kRotationalError, Statistic::kMean, "rotational error, eq. 2", true},
                   {"box", "", kPositionalError, Statistic::kMean, "positional error of the camera (units)", true},
                   {"box", "", kRotationDeg, Statistic::kMedian, "rotation error (degrees)", true},
                   {"box", "", kReprojectionError, Statistic::kMean, "reprojection error, eq. 1 (px)", true}};
  result.notes.push_back("the paper's noise is 0-1 mm on a 1 mm box; the scene here is unit-free: sigma 0-1 on a box of edge 1");
  result.notes.push_back("each trial: new box points and noise; pose by EPnP (cv::solvePnP SOLVEPNP_EPNP) from the "
                         "noisy 3D points and the exact 2D projections");
  return result;
}

}  // namespace tagsfm::analysis
