#pragma once
// Intrinsics from the targets themselves, for a recording without a camera
// block: each tag seen in a frame is a small planar calibration object of
// known size (its four corners), so OpenCV's calibrateCamera (Zhang's
// method, then LM) runs on all tag views together. With a known map, whole
// frames of map corners refine that estimate.
#include <optional>
#include <vector>

#include "tagsfm/capture/recording.h"
#include "tagsfm/core/camera_model.h"
#include "tagsfm/detect/tag_detection.h"

namespace tagsfm {

struct CalibrationOptions {
  int max_views = 400;              // tag views used (evenly subsampled beyond this)
  double min_tag_side_px = 20.0;    // smaller tags say little about the intrinsics
  bool estimate_k3 = false;         // 4 corners per view rarely support k3
  bool estimate_tangential = false;

  Status Check() const;
};

struct CalibrationResult {
  CameraModel camera;
  double rms_px = 0;   // OpenCV's reprojection RMS over the views used
  int views = 0;       // tag views used
  int frames = 0;      // frames that contributed
};

Result<CalibrationResult> CalibrateFromTargets(const std::vector<DetectionSet>& detections,
                                               const TargetConfig& targets, int width, int height,
                                               const std::optional<TargetCornerMap>& known_map,
                                               const CalibrationOptions& options);

}  // namespace tagsfm
