#pragma once
// Target coverage during a capture: which targets were seen, how often, and
// from what directions. A target seen only head-on, or only from one side,
// is poorly triangulated (depth along the viewing direction is weak) even
// after many frames; the directions tell the operator where to walk.
#include <array>
#include <map>
#include <vector>

#include "tagsfm/capture/recording.h"
#include "tagsfm/core/camera_model.h"
#include "tagsfm/detect/tag_detection.h"

namespace tagsfm {

// Directions are binned by the azimuth of the camera around the tag's
// normal (8 sectors of 45°), counting only views tilted at least
// kMinTiltForSectorDeg from head-on (a head-on view has no azimuth).
inline constexpr int kCoverageSectors = 8;
inline constexpr double kMinTiltForSectorDeg = 10.0;

struct TargetCoverage {
  TagId id = -1;
  int times_seen = 0;
  FrameId last_seen = 0;
  double min_tilt_deg = 90;      // angle between the tag's normal and the ray to the camera
  double max_tilt_deg = 0;
  double last_distance_m = 0;
  std::array<int, kCoverageSectors> sector_views{};

  int SectorsCovered() const;
  // Largest angle between any two viewing directions seen so far: what
  // triangulating the target's depth depends on.
  double direction_spread_deg = 0;
  std::vector<Eigen::Vector3d> directions_in_tag;  // a few spread-out unit directions, tag frame
};

// The geometry of one tag in one frame, from its own four corners.
struct TagSighting {
  TagId id = -1;
  double distance_m = 0;          // camera centre to tag centre
  double tilt_deg = 0;
  Eigen::Vector3d camera_direction_in_tag = Eigen::Vector3d::UnitZ();  // unit, tag frame
  Eigen::Vector3d centre_in_cam = Eigen::Vector3d::Zero();             // the tag's centre, camera frame
};

// Per-tag geometry of a frame's detections (IPPE on each tag's corners);
// tags whose pose cannot be found are left out.
std::vector<TagSighting> ComputeTagViews(const CameraModel& camera, const TargetConfig& targets,
                                     const DetectionSet& detections);

class CoverageTracker {
 public:
  void Add(FrameId frame, const std::vector<TagSighting>& views);
  const std::map<TagId, TargetCoverage>& targets() const { return targets_; }

 private:
  std::map<TagId, TargetCoverage> targets_;
};

}  // namespace tagsfm
