#pragma once
// Every setting of the pipeline, one struct per stage, as a user sets them
// in a `pipeline:` block (run config, or `replay --config`): the YAML field
// names are the struct field names (firmware_config/README.md).
#include <filesystem>

#include <yaml-cpp/yaml.h>

#include "tagsfm/detect/tag_detector.h"
#include "tagsfm/detect/tag_tracker.h"
#include "tagsfm/feedback/live_feedback.h"
#include "tagsfm/pipeline/feature_stage.h"
#include "tagsfm/pipeline/tag_search.h"
#include "tagsfm/recon/reconstructor.h"

namespace tagsfm {

struct PipelineOptions {
  TagSearch tag_search = TagSearch::kTracking;
  TagDetectorOptions detector;  // family: always the recording's targets.family
  TagTrackerOptions tracker;
  ReconstructorOptions recon;
  FeatureStageOptions features;
  // Live feedback per frame (run, replay --realtime): coverage, depth advice.
  bool live_feedback = false;
  LiveFeedbackOptions feedback;

  // The first wrong field, named as in the YAML block ("pipeline.recon.ba.huber_px must be > 0").
  Status Check() const;
};

// Reads a `pipeline:` block over `options` (fields left out keep their
// values). Errors name the file and the field; an unknown field is one.
Status ReadPipelineOptions(const YAML::Node& block, const std::filesystem::path& file, PipelineOptions* options);
// The `pipeline:` block of a YAML file (none: the defaults).
Result<PipelineOptions> ReadPipelineOptionsFile(const std::filesystem::path& file);

}  // namespace tagsfm
