// The sweep the paper could not run: tag corners through EPnP, EPnP + LM and
// this project's pose estimator, next to the error model's prediction.
#include <array>
#include <cmath>
#include <numbers>

#include "experiment_common.h"
#include "tagsfm/analysis/experiments.h"
#include "tagsfm/analysis/pose_solvers.h"
#include "tagsfm/recon/error_model.h"

namespace tagsfm::analysis {
namespace {

constexpr int kTagSites = 400;
constexpr double kTagEdge = 0.2;  // units (~ metres on the hull): a 20 cm tag

using TagCorners3d = std::array<Eigen::Vector3d, 4>;

// Square tags flat on the hull at random surface points, randomly turned.
std::vector<std::pair<SurfacePoint, TagCorners3d>> PlaceTags(const SyntheticObject& object, std::mt19937& rng) {
  std::uniform_int_distribution<int> pick(0, static_cast<int>(object.surface.size()) - 1);
  std::uniform_real_distribution<double> turn(0.0, 2.0 * std::numbers::pi);
  std::vector<std::pair<SurfacePoint, TagCorners3d>> tags;
  for (int i = 0; i < kTagSites; ++i) {
    const SurfacePoint& site = object.surface[pick(rng)];
    const Eigen::Vector3d helper = std::abs(site.normal.z()) < 0.9 ? Eigen::Vector3d::UnitZ() : Eigen::Vector3d::UnitX();
    const Eigen::Vector3d u0 = site.normal.cross(helper).normalized();
    const Eigen::Vector3d v0 = site.normal.cross(u0);
    const double angle = turn(rng);
    const Eigen::Vector3d u = std::cos(angle) * u0 + std::sin(angle) * v0;
    const Eigen::Vector3d v = site.normal.cross(u);
    const double h = 0.5 * kTagEdge;
    tags.push_back({site, {site.position + h * (-u - v), site.position + h * (u - v), site.position + h * (u + v),
                           site.position + h * (-u + v)}});
  }
  return tags;
}

bool TagVisible(const std::pair<SurfacePoint, TagCorners3d>& tag, const Rigid3d& cam_from_world, const CameraModel& camera) {
  if (tag.first.normal.dot(cam_from_world.Center() - tag.first.position) <= 0) return false;
  for (const Eigen::Vector3d& corner : tag.second) {
    const Eigen::Vector3d in_cam = cam_from_world * corner;
    if (in_cam.z() < 0.1) return false;
    const Eigen::Vector2d px = ProjectToPixel(camera, in_cam);
    if (px.x() < 0 || px.y() < 0 || px.x() > camera.width - 1 || px.y() > camera.height - 1) return false;
  }
  return true;
}

enum Metric { kRotation = 0, kPosition = 1, kFailed = 2 };
constexpr PoseSolver kSolvers[] = {PoseSolver::kEpnp, PoseSolver::kEpnpLm, PoseSolver::kPipeline};

using PlacedTags = std::vector<std::pair<SurfacePoint, TagCorners3d>>;

// The corners of `count` tags drawn from those in view: in the world, in
// the camera and in the image.
struct SampledCorners {
  std::vector<Eigen::Vector3d> world, in_cam;
  std::vector<Eigen::Vector2d> pixels;
};
SampledCorners SampleTagCorners(const PlacedTags& tags, const std::vector<int>& visible, int count,
                                const Rigid3d& cam_from_world, const CameraModel& camera, std::mt19937& rng) {
  SampledCorners c;
  for (int t : SampleWithoutReplacement(visible, count, rng)) {
    for (const Eigen::Vector3d& corner : tags[t].second) {
      c.world.push_back(corner);
      c.in_cam.push_back(cam_from_world * corner);
      c.pixels.push_back(ProjectToPixel(camera, c.in_cam.back()));
    }
  }
  return c;
}

// One noise level: the corners with noise (one draw for every solver),
// each solver's pose against the truth, and the error model's prediction.
void AddSolverErrors(const SampledCorners& c, double sigma, const Rigid3d& cam_from_world, const CameraModel& camera,
                     std::mt19937& rng, const Grid& grid, int facet, int x, Accumulator& out) {
  std::normal_distribution<double> noise(0.0, 1.0);
  std::vector<Eigen::Vector2d> noisy;
  for (const Eigen::Vector2d& p : c.pixels) noisy.push_back(p + sigma * Eigen::Vector2d(noise(rng), noise(rng)));
  for (int s = 0; s < 3; ++s) {
    const int condition = grid.Index(facet, s, x);
    const SolvedPose pose = SolvePose(kSolvers[s], c.world, noisy, camera);
    out.Add(condition, kFailed, pose.ok ? 0.0 : 1.0);
    if (!pose.ok) continue;
    const PoseErrors errors = ComparePoses(pose.cam_from_world, cam_from_world);
    out.Add(condition, kRotation, errors.rotation_deg);
    out.Add(condition, kPosition, errors.position);
  }
  const Result<Eigen::Matrix<double, 6, 6>> covariance =
      PoseCovariance(c.in_cam, camera.fx, std::vector<double>(c.in_cam.size(), sigma));
  if (!covariance) return;
  const PoseErrorRms predicted = PoseErrorFromCovariance(*covariance);
  const int condition = grid.Index(facet, 3, x);
  out.Add(condition, kRotation, predicted.rotation_deg);
  out.Add(condition, kPosition, predicted.position_m);
}

}  // namespace

ExperimentResult RunPipeline(const ExperimentOptions& options) {
  ExperimentResult result;
  result.name = "pipeline";
  result.title = "Tag corners: EPnP vs EPnP+LM vs tagsfm's estimator vs the error model (bradley-like)";
  result.facet_column = "corner_noise_px";
  result.facet_title = "corner noise σ = %s px";
  result.series_column = "solver";
  result.series_legend = "%s";
  result.x_column = "tags";
  result.x_label = "tags in view (4 corners each)";
  result.log_x = true;
  result.trials = options.trials;
  const std::vector<double> sigmas = {0.25, 1, 3};
  Grid grid;
  grid.facets.clear();
  for (double sigma : sigmas) grid.facets.push_back(FormatValue(sigma));
  grid.series = {PoseSolverName(kSolvers[0]), PoseSolverName(kSolvers[1]), PoseSolverName(kSolvers[2]), "model"};
  grid.xs = {2, 3, 5, 10, 20, 50};
  const CameraModel camera = ExperimentCamera();
  const SyntheticObject object = MakeVehicle(VehicleKind::kBradleyLike, ItemSeed(options.seed, 100, 0));
  std::mt19937 tag_rng(ItemSeed(options.seed, 6, 0));
  const PlacedTags tags = PlaceTags(object, tag_rng);
  const int total = static_cast<int>(object.cameras.size());
  const int used = std::min(options.trials, total);
  const Accumulator values = ParallelSweep(used, grid.Conditions(), 3, options.threads, [&](int item, Accumulator& out) {
    const int camera_index = static_cast<int>(static_cast<long long>(item) * total / used);
    const Rigid3d& cam_from_world = object.cameras[camera_index];
    std::mt19937 rng(ItemSeed(options.seed, 7, camera_index));
    std::vector<int> visible;
    for (int t = 0; t < kTagSites; ++t) {
      if (TagVisible(tags[t], cam_from_world, camera)) visible.push_back(t);
    }
    for (size_t x = 0; x < grid.xs.size(); ++x) {
      const int count = static_cast<int>(grid.xs[x]);
      if (count > static_cast<int>(visible.size())) continue;
      const SampledCorners corners = SampleTagCorners(tags, visible, count, cam_from_world, camera, rng);
      for (size_t f = 0; f < sigmas.size(); ++f) {
        AddSolverErrors(corners, sigmas[f], cam_from_world, camera, rng, grid, static_cast<int>(f), static_cast<int>(x),
                        out);
      }
    }
  });
  AddRows(result, object.name, grid, {kRotationDeg, kPositionalError, "failure_rate"}, values);
  for (const std::string& facet : grid.facets) {
    result.panels.push_back({object.name, facet, kRotationDeg, Statistic::kRms, "rotation error (degrees)", true});
    result.panels.push_back({object.name, facet, kPositionalError, Statistic::kRms, "camera position error (units)", true});
    result.panels.push_back({object.name, facet, "failure_rate", Statistic::kMean, "fraction not registered", false});
  }
  result.panel_columns = 3;
  result.notes.push_back("20 cm tags (4 corners each) on 400 random sites of the bradley-like hull; one trial = one "
                         "camera of its set; corner noise: Gaussian per pixel coordinate, the same draw for all solvers");
  result.notes.push_back("tagsfm = recon's EstimatePose with default options (RANSAC EPnP, checks, robust LM); its "
                         "errors are over registered trials only; model = the error model's PoseCovariance for the "
                         "same corners (RMS, Cramer-Rao bound)");
  return result;
}

}  // namespace tagsfm::analysis
