#include "tagsfm/analysis/experiments.h"

#include <chrono>

namespace tagsfm::analysis {

Status ExperimentOptions::Check() const {
  if (trials < 0) return MakeError("--trials must be >= 0 (0: the experiment's default; got " + std::to_string(trials) + ")");
  if (threads < 0) return MakeError("threads must be >= 0 (got " + std::to_string(threads) + ")");
  return Status::Ok();
}

// Default trials: all experiments together run in a few minutes on 2 cores
// (docs/analysis.md has the measured times).
const std::vector<ExperimentInfo>& ExperimentCatalogue() {
  static const std::vector<ExperimentInfo> catalogue = {
      {"depth-image-noise", "paper 4.1.1, fig. 2", "camera depth vs 3D error of a point on a noisy ray, image noise 0-5 px",
       1000, "point sets of 100 box points"},
      {"depth-point-noise", "paper 4.1.2, fig. 3", "camera depth vs EPnP pose from 3D points with noise 0-1 (box edge 1)",
       1000, "point sets of 100 box points"},
      {"targets-image-noise", "paper 4.2.1, fig. 5", "5-1000 correspondences vs EPnP pose, image noise 0-10 px", 1234,
       "cameras per object (at most its set: 1234 / 278)"},
      {"targets-point-noise", "paper 4.2.2, fig. 6", "5-1000 correspondences vs EPnP pose, 3D noise 0-5 units", 1234,
       "cameras per object (at most its set: 1234 / 278)"},
      {"target-distribution", "paper 4.2.3, fig. 7", "50 targets clustered vs spread, image noise 0-10 px", 1234,
       "cameras per object (at most its set: 1234 / 278)"},
      {"pipeline", "beyond the paper",
       "2-50 tags: EPnP vs EPnP+LM vs tagsfm's pose estimator vs the error model, corner noise 0.25-3 px", 1234,
       "cameras of the bradley-like set"},
      {"pipeline-map", "beyond the paper",
       "whole target pipeline (Reconstructor, sliding-window + final BA, no known map) vs distance 1.25-3.5 m and "
       "corner noise 0.1-1 px",
       12, "walk-arounds (tag layouts and camera paths) per condition"},
      {"hybrid", "beyond the paper",
       "hybrid feature points through the whole pipeline on rendered walks (true target map) vs distance 1-3 m and "
       "image noise 1-8 grey levels, next to the error model's σ",
       1, "rendered scenes per condition"},
  };
  return catalogue;
}

Result<ExperimentResult> RunExperiment(const std::string& name, const ExperimentOptions& options) {
  if (Status ok = options.Check(); !ok) return ok.error();
  const ExperimentInfo* info = nullptr;
  std::string known;
  for (const ExperimentInfo& candidate : ExperimentCatalogue()) {
    if (candidate.name == name) info = &candidate;
    known += (known.empty() ? "" : ", ") + candidate.name;
  }
  if (info == nullptr) return MakeError("unknown experiment '" + name + "' (known: " + known + ")");
  ExperimentOptions run = options;
  if (run.trials == 0) run.trials = info->default_trials;
  using Runner = ExperimentResult (*)(const ExperimentOptions&);
  const std::pair<const char*, Runner> runners[] = {
      {"depth-image-noise", &RunDepthImageNoise},     {"depth-point-noise", &RunDepthPointNoise},
      {"targets-image-noise", &RunTargetsImageNoise}, {"targets-point-noise", &RunTargetsPointNoise},
      {"target-distribution", &RunTargetDistribution}, {"pipeline", &RunPipeline},
      {"pipeline-map", &RunPipelineMap},              {"hybrid", &RunHybrid}};
  for (const auto& [runner_name, runner] : runners) {
    if (name != runner_name) continue;
    const auto start = std::chrono::steady_clock::now();
    ExperimentResult result = runner(run);
    result.runtime_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return result;
  }
  return MakeError("experiment '" + name + "' has no runner");
}

}  // namespace tagsfm::analysis
