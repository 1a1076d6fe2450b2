#pragma once
// `replay --no-targets`: feature SfM alone on a recording's frames, the
// paper's SfM-only baseline (its VisualSFM) run by our own code: SIFT on
// every frame (or every Nth), the incremental mapper of sfm/, and the result
// in the shapes the writers take. The scale is arbitrary (the initial pair's
// baseline is 1); report.json says so.
#include <functional>

#include "tagsfm/capture/recording.h"
#include "tagsfm/feature/feature_extractor.h"
#include "tagsfm/pipeline/pipeline.h"
#include "tagsfm/sfm/incremental_mapper.h"

namespace tagsfm {

struct SfmAloneOptions {
  int frame_step = 1;  // every Nth frame of the recording (1: all, as COLMAP gets them in bench/compare_colmap.sh)
  // SIFT as the hybrid's (RootSIFT, contrast 0.02), capped at COLMAP's
  // default of 8192 per image. Tags are not masked: SfM alone knows nothing
  // of targets, and COLMAP, the other baseline, sees them as texture too.
  FeatureExtractorOptions features = [] {
    FeatureExtractorOptions o;
    o.max_features = 8192;
    return o;
  }();
  sfm::IncrementalMapperOptions mapper;
  Status Check() const;  // names the wrong field
};

// The mode report.json names for these runs (its "scale_kind" is then "arbitrary").
inline constexpr const char* kSfmAloneMode = "sfm alone";

// Reads the frames, extracts features, reconstructs. Unreadable frames are
// skipped and named; frames the mapper cannot register are unregistered with
// a reason. An error (one line) for a recording without intrinsics or
// without an initial pair (too few matches, pure rotation, no texture).
Result<PipelineResult> RunSfmAlone(const RecordingReader& reader, const SfmAloneOptions& options,
                                   const std::function<void(size_t done, size_t total)>& on_progress = {});

}  // namespace tagsfm
