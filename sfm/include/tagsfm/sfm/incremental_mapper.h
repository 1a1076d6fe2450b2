#pragma once
// Feature SfM alone, after COLMAP's incremental mapper
// (src/colmap/sfm/incremental_mapper.cc): match every pair of views (or
// those within a window), verify them by the essential matrix, start from
// the pair with the most inliers at a wide enough triangulation angle, then
// register the view that sees most triangulated points by PnP, triangulate
// its new tracks, adjust locally, and globally as the model grows; at the
// end a global adjustment, track completion and filtering. Scale arbitrary.
#include <vector>

#include "tagsfm/core/camera_model.h"
#include "tagsfm/core/result.h"
#include "tagsfm/feature/feature_extractor.h"
#include "tagsfm/sfm/bundle_adjustment.h"
#include "tagsfm/sfm/geometry.h"
#include "tagsfm/sfm/sfm_model.h"
#include "tagsfm/sfm/two_view.h"

namespace tagsfm::sfm {

struct IncrementalMapperOptions {
  double ratio = 0.8;             // Lowe's ratio test (COLMAP's max_ratio)
  int match_window = 0;           // match views at most this far apart in order; 0: every pair
  double max_error_px = 4.0;      // two-view RANSAC threshold and the triangulation/filter limit (COLMAP's 4)
  double abs_pose_max_error_px = 12.0;
  int abs_pose_min_inliers = 30;
  int init_min_inliers = 100;     // COLMAP's init_min_num_inliers
  double init_min_angle_deg = 16; // COLMAP's init_min_tri_angle; halved (with the inliers) until a pair qualifies
  double min_angle_deg = 1.5;     // new points and the final filter (COLMAP's min/filter_min_tri_angle)
  int local_ba_images = 6;        // COLMAP's ba_local_num_images
  double global_ba_growth = 1.2;  // a global adjustment each time the registered views grow by this factor
  double huber_px = 1.0;
  int max_registration_trials = 2;
  Status Check() const;
};

struct MapperStats {
  int pairs_matched = 0, pairs_verified = 0;
  ImageIdx init_a = -1, init_b = -1;
  int init_inliers = 0;
  double init_angle_deg = 0;
  int global_adjustments = 0, local_adjustments = 0;
  bool final_adjustment_usable = false;
  double matching_s = 0, mapping_s = 0;
};

struct MapperResult {
  SfmModel model;
  MapperStats stats;
};

// One view per entry of `views` (features as ExtractFeatures gives them),
// all from `camera`. Views that could not be registered stay unregistered
// with a reason; an error only when no initial pair exists (too few matches,
// pure rotation, no texture), naming why.
Result<MapperResult> ReconstructIncremental(const std::vector<KeyframeFeatures>& views, const CameraModel& camera,
                                            const IncrementalMapperOptions& options);

// A point's reprojection RMS in the images' pixels (through the lens model,
// against the features as detected) and its largest triangulation angle.
struct PointFit {
  double rms_px = 0;
  double max_angle_deg = 0;
};
PointFit FitOfPoint(const SfmModel& model, PointIdx point, const CameraModel& camera);

}  // namespace tagsfm::sfm
