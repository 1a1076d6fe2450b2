#pragma once
// Rendering a whole recording with its ground truth (docs/synth.md):
//   REC/recording.yaml, frames.csv, frames/*.png        (the contract's recording)
//   REC/ground_truth/poses.csv, targets.csv, scene.yaml (the truth)
//   REC/targets.csv                                     (only with with_map)
#include <filesystem>
#include <string>

#include "tagsfm/core/result.h"
#include "tagsfm/synth/scene.h"
#include "tagsfm/synth/synth_options.h"

namespace tagsfm::synth {

struct SynthSummary {
  int frames = 0;
  int targets = 0;
  double render_seconds = 0.0;  // ray casting and sensor model
  double total_seconds = 0.0;   // including scene set-up and PNG writing
};

Result<SynthSummary> WriteSyntheticRecording(const SynthOptions& options, const std::filesystem::path& dir);

// ground_truth/scene.yaml: the faces as rectangles, the tags, the render options.
std::string SceneYamlText(const Scene& scene, const SynthOptions& options);

}  // namespace tagsfm::synth
