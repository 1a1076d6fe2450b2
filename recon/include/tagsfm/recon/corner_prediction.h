#pragma once
// Where the mapped tags will appear in a frame, for tag tracking
// (TagTracker::Track's `predicted`): the map projected with an extrapolated
// pose. Such a prediction also covers tags the tracker has not seen lately
// (one that turns into view round the object's corner, or comes out from
// behind an occluder), which the tracker alone finds only at its next
// full-frame pass.
#include <map>
#include <optional>

#include "tagsfm/core/camera_model.h"
#include "tagsfm/core/rigid3d.h"
#include "tagsfm/detect/corner_refinement.h"
#include "tagsfm/detect/tag_detection.h"
#include "tagsfm/recon/reconstruction.h"

namespace tagsfm {

struct CornerPredictionOptions {
  // Tags seen more obliquely than this (angle between the tag's normal and
  // the ray to it) are left out: libapriltag finds few beyond ~70 degrees.
  double max_view_angle_deg = 75.0;
  // Tags smaller than this (mean side, px) are left out: 8 modules across
  // at under 1.25 px each are not found.
  double min_side_px = 10.0;
  // Only tags wholly inside the image, this many pixels clear of its border.
  double border_margin_px = 2.0;
  Status Check() const;
};

// The corners of every tag of `tags` that `cam_from_world` sees in front of
// it, facing it, large enough and inside the image (libapriltag's order).
std::map<TagId, QuadCorners> ProjectMappedTags(const CameraModel& camera, const Rigid3d& cam_from_world,
                                               const std::map<TagId, MapTag>& tags,
                                               const CornerPredictionOptions& options);

// The pose at `frame` from the two registered poses before it, at constant
// velocity (rotation and translation per frame extrapolated along the
// geodesic); the last pose alone when there is no earlier one. The
// extrapolation is limited to `max_steps` times the last motion, beyond
// which a constant velocity says little.
Rigid3d ExtrapolatePose(const Rigid3d& last, FrameId last_frame, const std::optional<Rigid3d>& before,
                        FrameId before_frame, FrameId frame, double max_steps = 4.0);

}  // namespace tagsfm
