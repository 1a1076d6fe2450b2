#pragma once
// Feature points from tracks over any number of keyframes and the final
// (target-derived) poses: linear start, the angular-error refinement over
// every view (the paper's ref. 5, feature_triangulation.h), views far off
// the refined point dropped one at a time and the point refined again, then
// kept by reprojection error, triangulation angle, cheirality and the
// predicted sigma.
#include <array>
#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "tagsfm/core/camera_model.h"
#include "tagsfm/core/csv_formats.h"
#include "tagsfm/core/result.h"
#include "tagsfm/feature/feature_triangulation.h"

namespace tagsfm {

struct TrackObservation {
  FrameId frame = 0;
  int feature = -1;                                 // index in that keyframe's KeyframeFeatures
  Eigen::Vector2d pixel = Eigen::Vector2d::Zero();  // distorted, OpenCV convention
  std::array<std::uint8_t, 3> rgb{0, 0, 0};
  // This view's localisation noise, px, when known (a least-squares fit's
  // own estimate); 0: the triangulation's feature_sigma_px.
  double sigma_px = 0;
};

// One scene point's observations, at most one per keyframe.
struct FeatureTrack {
  TrackId id = -1;
  std::vector<TrackObservation> observations;
};

struct TrackTriangulationOptions {
  int min_views = 2;            // views left after outlier removal
  double min_angle_deg = 2.0;   // widest angle between two of the point's rays
  // A view whose reprojection is further than this from the refined point
  // is dropped (the worst first) and the point refined again.
  double max_view_error_px = 2.0;
  double max_reprojection_rms_px = 1.0;  // over the kept views
  // The feature localisation noise the predicted sigma assumes, px; also the
  // floor of the noise behind the stored covariance, and of each view's own
  // sigma_px: a view known to be worse weighs (feature_sigma_px / sigma_px)^2.
  double feature_sigma_px = 0.5;
  // Largest axis of the predicted covariance (at feature_sigma_px) over the
  // distance to the nearest camera; wider is dropped (narrow rays).
  double max_relative_sigma = 2e-3;
  // A higher floor of the noise behind the stored covariance only (not of
  // the filter above), px: the views' error the data themselves show
  // (FeatureMap sets the fits' limit, FeatureTriangulationStats::max_fit_sigma_px),
  // so that a view's fit sigma, which knows nothing of the poses or of its
  // own model error, does not make the point look better than the typical
  // view allows. 0: feature_sigma_px alone.
  double covariance_floor_px = 0;
  int max_iterations = 10;

  Status Check() const;  // names the wrong field
};

// Why tracks gave no point, counted over one TriangulateTracks call (the
// reasons in the order they are tested; each track counts once).
struct TrackTriangulationStats {
  int tracks = 0;
  int points = 0;
  int too_few_views = 0;     // under min_views with a pose, or after dropping views beyond max_view_error_px
  int no_linear_point = 0;   // the DLT found no point (rays parallel or degenerate)
  int reprojection = 0;      // RMS over the kept views above max_reprojection_rms_px
  int narrow_angle = 0;      // widest ray angle below min_angle_deg
  int predicted_sigma = 0;   // predicted sigma above max_relative_sigma of the distance

  TrackTriangulationStats& operator+=(const TrackTriangulationStats& other);
};

// Where FeatureMap::Triangulate's tracks went: the first pass (SIFT pixels, no sigma
// filter), the tracks the least-squares refinement dropped
// (track_refinement.h), the final pass (refined pixels). Without refinement, only `final_pass`.
struct FeatureTriangulationStats {
  TrackTriangulationStats first_pass;
  // The epipolar lines' error across themselves measured from the free
  // fits, px (0: not measured), and the views fitted along a line.
  double epipolar_sigma_px = 0;
  double max_fit_sigma_px = 0;  // the fits' limit that follows from it (FeatureMapOptions), 0: not measured
  int line_fits = 0;
  int tilted_fits = 0;  // views accepted from a tilted plane's start (PatchRefinementOptions::tilt_retries)
  int refinement_dropped = 0;
  TrackTriangulationStats final_pass;
};

// Points of the tracks whose views are in `cam_from_world`; FeaturePoint's
// track is the track's id, its observations the views kept, its covariance
// sigma^2 (J^T J)^-1 of the angular residuals with sigma the larger of its
// reprojection RMS (corrected for the 3 fitted parameters) and
// feature_sigma_px, over fx. Sorted by track id; the same for any number
// of `threads` (tracks are independent).
std::vector<FeaturePoint> TriangulateTracks(const std::vector<FeatureTrack>& tracks, const PoseMap& cam_from_world,
                                            const CameraModel& camera, const TrackTriangulationOptions& options,
                                            int threads = 1, TrackTriangulationStats* stats = nullptr);

}  // namespace tagsfm
