// The hybrid's feature points through the real pipeline: walks round synth's
// box rendered at several distances and image noises, replayed with the true
// target map (the poses are then the targets', so what is measured is the
// features' own error), each point's distance to the true surface against
// the error model's σ along that surface's normal (the point's covariance,
// FeaturePoint::covariance, from its rays and its reprojection RMS).
#include <algorithm>
#include <atomic>
#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include <unistd.h>

#include "experiment_common.h"
#include "tagsfm/analysis/experiments.h"
#include "tagsfm/analysis/statistics.h"
#include "tagsfm/capture/recording.h"
#include "tagsfm/eval/scene_geometry.h"
#include "tagsfm/pipeline/drivers.h"
#include "tagsfm/pipeline/pipeline.h"
#include "tagsfm/synth/synthetic_recording.h"

namespace tagsfm::analysis {
namespace {

enum Metric { kErrorMedian = 0, kSigmaMedian = 1, kWithinTwoSigma = 2, kPoints = 3, kMetrics = 4 };

// A rendered recording in a folder of its own, removed when done.
class ScratchDir {
 public:
  explicit ScratchDir(const std::string& tag) {
    static std::atomic<int> counter{0};
    path_ = std::filesystem::temp_directory_path() /
            ("tagsfm-hybrid-" + std::to_string(::getpid()) + "-" + std::to_string(counter++) + "-" + tag);
  }
  ~ScratchDir() {
    std::error_code ignored;
    std::filesystem::remove_all(path_, ignored);
  }
  const std::filesystem::path& path() const { return path_; }

 private:
  std::filesystem::path path_;
};

}  // namespace

Result<HybridWalkFigures> MeasureHybridWalk(const synth::SynthOptions& render) {
  ScratchDir dir(std::to_string(render.seed) + "-" + std::to_string(render.noise) + "-" + std::to_string(render.min_distance));
  if (auto written = synth::WriteSyntheticRecording(render, dir.path()); !written) return written.error();
  auto reader = RecordingReader::Open(dir.path());
  if (!reader) return reader.error();
  auto map = ReadTargetsCsv(dir.path() / "ground_truth/targets.csv");
  if (!map) return map.error();
  auto surfaces = eval::ReadSceneYaml(dir.path() / "ground_truth/scene.yaml");
  if (!surfaces) return surfaces.error();
  PipelineOptions options;  // the defaults, one thread each: the sweep runs one walk per core
  options.detector.threads = 1;
  options.features.match_threads = 1;
  options.features.finish_threads = 1;
  options.recon.ba.global_threads = 1;
  auto pipeline = Pipeline::Create(PipelineInput{reader->info(), *map, RecordingFrameLoader(*reader)}, options);
  if (!pipeline) return pipeline.error();
  ReplayRecording(*reader, **pipeline, ReplayLoopOptions{});
  const Result<PipelineResult> result = (*pipeline)->Finish();
  if (!result) return result.error();
  // Medians and a share, not RMS: a few points on the wrong surface (a
  // mismatch that passed every check) would otherwise decide the figure.
  std::vector<double> errors, sigmas;
  int within = 0;
  for (const FeaturePoint& p : result->reconstruction.feature_points) {
    double distance = 0;
    const eval::SurfaceRectangle* surface = eval::NearestSurface(*surfaces, p.position, &distance);
    if (surface == nullptr) continue;
    const Eigen::Vector3d normal = surface->edge_u.cross(surface->edge_v).normalized();
    const double sigma = std::sqrt(std::max(0.0, normal.dot(p.covariance * normal)));
    if (!(sigma > 0)) continue;
    errors.push_back(distance);
    sigmas.push_back(sigma);
    if (distance <= 2.0 * sigma) ++within;
  }
  HybridWalkFigures figures;
  figures.points = static_cast<int>(errors.size());
  if (errors.empty()) return figures;
  figures.error_median_m = Summarize(errors).median;
  figures.sigma_median_m = Summarize(sigmas).median;
  figures.within_two_sigma = static_cast<double>(within) / static_cast<double>(errors.size());
  return figures;
}

ExperimentResult RunHybrid(const ExperimentOptions& options) {
  ExperimentResult result;
  result.name = "hybrid";
  result.title = "Hybrid feature points (true target map): camera distance and image noise vs point error";
  result.series_column = "image_noise_grey";
  result.series_legend = "noise %s grey levels";
  result.x_column = "distance_m";
  result.x_label = "camera distance to the box centre (m; ±15 % per view)";
  result.trials = options.trials;
  Grid grid;
  const std::vector<double> noises = {1.0, 2.0, 4.0, 8.0};
  for (double noise : noises) grid.series.push_back(FormatValue(noise));
  grid.xs = {1.5, 2.0, 2.5, 3.0};
  const int walks = grid.Conditions();
  const Accumulator values =
      ParallelSweep(options.trials * walks, walks, kMetrics, options.threads, [&](int item, Accumulator& out) {
        const int trial = item / walks, walk = item % walks;
        const int s = walk / static_cast<int>(grid.xs.size()), x = walk % static_cast<int>(grid.xs.size());
        synth::SynthOptions render;  // the box, 10 views ~7 degrees apart, 1280x720, blur 0.7
        render.frames = 10;
        render.max_azimuth_deg = 30.0;
        render.min_distance = 0.85 * grid.xs[x];
        render.max_distance = 1.15 * grid.xs[x];
        render.noise = noises[s];
        render.threads = 1;
        // The same scene and path for every condition of a trial; the noise differs.
        render.seed = ItemSeed(options.seed, 10, static_cast<std::uint32_t>(trial));
        const Result<HybridWalkFigures> figures = MeasureHybridWalk(render);
        if (!figures) return;  // counted: the condition's n is short of the trials
        const int condition = grid.Index(0, s, x);
        out.Add(condition, kPoints, figures->points);
        if (figures->points == 0) return;
        out.Add(condition, kErrorMedian, 1000.0 * figures->error_median_m);
        out.Add(condition, kSigmaMedian, 1000.0 * figures->sigma_median_m);
        out.Add(condition, kWithinTwoSigma, figures->within_two_sigma);
      });
  AddRows(result, "box", grid, {"point_error_median_mm", "predicted_sigma_median_mm", "within_2_sigma", "points"},
          values);
  result.panels = {
      {"box", "", "point_error_median_mm", Statistic::kMedian, "feature points: median distance to the true surface (mm)",
       true},
      {"box", "", "predicted_sigma_median_mm", Statistic::kMedian, "error model: median σ along the surface normal (mm)",
       true},
      {"box", "", "within_2_sigma", Statistic::kMedian, "share of points within 2σ (honest Gaussian σ: 0.95)", false},
      {"box", "", "points", Statistic::kMedian, "feature points per walk", false}};
  result.notes.push_back(
      "synth's box scene (tag margin 1, blur 0.7 px), 10 frames of 1280x720 (fx 1000 px) on a 60-degree arc, rendered "
      "and replayed through tagsfm's pipeline with default options and the true target map (poses from the targets); "
      "a point's error is its distance to the nearest true surface, its σ the error model's along that surface's "
      "normal; one trial = one scene, texture and path, shared by every condition");
  return result;
}

}  // namespace tagsfm::analysis
