#pragma once
// The paper's synthetic experiments (section 4.1-4.2) and the sweep it could
// not run (the project's own pose pipeline), by name:
//   depth-image-noise    4.1.1, fig. 2: positional error of a point on a noisy ray vs camera depth
//   depth-point-noise    4.1.2, fig. 3: EPnP pose from noisy 3D points vs camera depth
//   targets-image-noise  4.2.1, fig. 5: EPnP pose vs number of correspondences, image noise
//   targets-point-noise  4.2.2, fig. 6: EPnP pose vs number of correspondences, 3D noise
//   target-distribution  4.2.3, fig. 7: 50 points clustered vs spread
//   pipeline             EPnP vs EPnP+LM vs tagsfm's estimator vs the error model, on tag corners
//   pipeline-map         the whole target pipeline (recon's Reconstructor, no known map) vs distance and noise
//   hybrid               the feature points through the whole pipeline on rendered walks vs distance and image noise
#include <cstdint>
#include <string>
#include <vector>

#include "tagsfm/analysis/experiment_result.h"
#include "tagsfm/core/result.h"
#include "tagsfm/synth/synth_options.h"

namespace tagsfm::analysis {

struct ExperimentOptions {
  int trials = 0;          // 0: the experiment's default (ExperimentInfo::default_trials)
  std::uint32_t seed = 1;  // the same seed gives the same numbers, on any number of threads
  int threads = 0;         // 0: all cores

  Status Check() const;
};

struct ExperimentInfo {
  std::string name;
  std::string paper_section;  // "paper 4.1.1, fig. 2" or "beyond the paper"
  std::string summary;
  int default_trials = 0;
  std::string trial_unit;     // what one trial is, e.g. "cameras per object"
};

// Every experiment, in the paper's order.
const std::vector<ExperimentInfo>& ExperimentCatalogue();

// An error for an unknown name or bad options.
Result<ExperimentResult> RunExperiment(const std::string& name, const ExperimentOptions& options);

// The individual experiments (options already checked, trials > 0).
ExperimentResult RunDepthImageNoise(const ExperimentOptions& options);
ExperimentResult RunDepthPointNoise(const ExperimentOptions& options);
ExperimentResult RunTargetsImageNoise(const ExperimentOptions& options);
ExperimentResult RunTargetsPointNoise(const ExperimentOptions& options);
ExperimentResult RunTargetDistribution(const ExperimentOptions& options);
ExperimentResult RunPipeline(const ExperimentOptions& options);
ExperimentResult RunPipelineMap(const ExperimentOptions& options);
ExperimentResult RunHybrid(const ExperimentOptions& options);

// One of the hybrid sweep's walks: rendered, replayed with its true map, its
// feature points against the true surfaces.
struct HybridWalkFigures {
  int points = 0;
  double error_median_m = 0;     // distance to the nearest true surface
  double sigma_median_m = 0;     // the error model's, along that surface's normal
  double within_two_sigma = 0;   // share of points with error <= 2 sigma
};
Result<HybridWalkFigures> MeasureHybridWalk(const synth::SynthOptions& render);

}  // namespace tagsfm::analysis
