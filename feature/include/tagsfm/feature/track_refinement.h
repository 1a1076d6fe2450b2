#pragma once
// Multi-photo least-squares matching of a track: every view of a
// triangulated point is fitted (patch_refinement.h) to one reference view,
// the warp predicted from the known poses and a plane through the point
// facing the cameras (or, when that fit is refused, tilted from it:
// PatchRefinementOptions::tilt_retries). The reference keeps its SIFT
// pixel; its own error only slides the point along the surface, while the
// other views now see the same surface point to a few hundredths of a
// pixel, so the depth along narrow rays is no longer set by SIFT's
// localisation.
#include <functional>
#include <vector>

#include <opencv2/core.hpp>

#include "tagsfm/core/camera_model.h"
#include "tagsfm/core/csv_formats.h"
#include "tagsfm/feature/feature_triangulation.h"
#include "tagsfm/feature/patch_refinement.h"
#include "tagsfm/feature/track_triangulation.h"

namespace tagsfm {

// The keyframe's grey image at pyramid level `level` (0: full size, each
// level halved by cv::pyrDown), or nullptr when it has none.
using KeyframeImageLookup = std::function<const cv::Mat*(FrameId, int level)>;

// The affine map, at `point`, from the reference view's image to the
// target view's, of a plane through `point` with unit normal `normal`.
Eigen::Matrix2d PredictPatchAffine(const Eigen::Vector3d& point, const Eigen::Vector3d& normal, const Rigid3d& reference,
                                   const Rigid3d& target, const CameraModel& camera);

// What RefineTrackViews saw besides the track.
struct TrackRefinementReport {
  // Each free fit's signed distance across its reference pixel's epipolar
  // line, px: the poses' and the lens' error there, and the fit's noise.
  std::vector<double> across_epipolar_px;
  int line_fits = 0;  // views of the kept track fitted along the line after their free fit was refused
  int tilted_fits = 0;  // views of the kept track accepted from a tilted plane's start (tilt_retries)
};

// `track`'s views that are in `point` (a first triangulation of it), each
// but the reference moved to where the reference patch fits. A view whose
// free fit is refused is fitted again along the reference pixel's
// epipolar line (PatchLine) when `epipolar_sigma_px` (the line's error
// across itself) is above 0: an edge across the line then gives the depth
// that the free fit, sliding along the edge, cannot. A view refused both
// ways keeps its own pixel with sigma_px = `unrefined_sigma_px` (its
// detector's noise), or is dropped when that is 0. The reference is
// the view nearest the mean viewing direction; the fits run on the level
// that the reference feature's scale asks for (PatchRefinementOptions::
// level_scale_px). Views are left out when they have no image. An empty track when fewer than two views remain,
// or when no fit succeeded and fewer than three do: two unrefined views
// cannot tell a wrong match from a right one, a third must agree with them.
FeatureTrack RefineTrackViews(const FeatureTrack& track, const FeaturePoint& point, const PoseMap& cam_from_world,
                              const KeyframeImageLookup& image_of, const CameraModel& camera,
                              const PatchRefinementOptions& options, double unrefined_sigma_px = 0,
                              double epipolar_sigma_px = 0, TrackRefinementReport* report = nullptr);

}  // namespace tagsfm
