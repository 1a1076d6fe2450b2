#pragma once
// The state a reconstruction is made of, as plain values: frames with their
// tag observations and poses, and the target map (tags as rigid squares of
// known size, or corners held fixed from a known map).
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "tagsfm/capture/recording.h"
#include "tagsfm/core/camera_model.h"
#include "tagsfm/core/csv_formats.h"
#include "tagsfm/feature/feature_triangulation.h"
#include "tagsfm/recon/pose_estimator.h"
#include "tagsfm/recon/pose_params.h"

namespace tagsfm {

// One tag seen in one frame: its corners in pixels (distorted, as detected)
// and undistorted to normalised image coordinates.
struct TagObservation {
  TagId id = -1;
  std::array<Eigen::Vector2d, 4> pixels{Eigen::Vector2d::Zero(), Eigen::Vector2d::Zero(), Eigen::Vector2d::Zero(),
                                        Eigen::Vector2d::Zero()};
  std::array<Eigen::Vector2d, 4> normalized{Eigen::Vector2d::Zero(), Eigen::Vector2d::Zero(),
                                            Eigen::Vector2d::Zero(), Eigen::Vector2d::Zero()};
  // A corner of it disagrees with the rest of the frame (e.g. a tag cut by
  // the image border): left out of the adjustments and the RMS figures.
  bool outlier = false;
  // Each corner's residual weight W from the detector's covariance C
  // (TagDetection::corner_covariance): W^T W = sigma_ref^2 C^-1, so a corner
  // counts by its own precision and one at the reference sigma as before.
  // In the normalized residuals' units (undistorted pixels) and in image
  // pixels (when the intrinsics are adjusted). Identity when C is unknown.
  std::array<Eigen::Matrix2d, 4> weight_undistorted{Eigen::Matrix2d::Identity(), Eigen::Matrix2d::Identity(),
                                                    Eigen::Matrix2d::Identity(), Eigen::Matrix2d::Identity()};
  std::array<Eigen::Matrix2d, 4> weight_pixels{Eigen::Matrix2d::Identity(), Eigen::Matrix2d::Identity(),
                                               Eigen::Matrix2d::Identity(), Eigen::Matrix2d::Identity()};
  // The detector's covariance of each corner in pixels (zero: unknown),
  // which the weights are made from once the corners' noise floor is known.
  std::array<Eigen::Matrix2d, 4> corner_covariance{Eigen::Matrix2d::Zero(), Eigen::Matrix2d::Zero(),
                                                   Eigen::Matrix2d::Zero(), Eigen::Matrix2d::Zero()};
};

// A corner's error variance as scale^2 C + floor_px^2, C the detector's covariance.
struct CornerNoiseModel {
  double scale = 1.0;
  double floor_px = 0.0;
};

struct FrameState {
  FrameId frame = 0;
  std::vector<TagObservation> tags;
  bool registered = false;
  bool keyframe = false;
  PoseMethod method = PoseMethod::kNone;
  bool fell_back = false;
  std::string reason;          // why unregistered
  double pnp_rms_px = 0;
  PoseParams cam_from_world;   // valid when registered
  // Its tag views were given back to keep a long capture's memory bounded
  // (ReconstructorOptions::max_retained_frames): the pose stays as
  // registered live, and the final adjustment does without it.
  bool thinned = false;

  const TagObservation* Find(TagId id) const {
    for (const auto& t : tags) {
      if (t.id == id) return &t;
    }
    return nullptr;
  }
};

// A target of the map. A known tag keeps the corners of the given map, held
// fixed; a learned tag is a pose plus its known size.
struct MapTag {
  TagId id = -1;
  double size_m = 0;
  bool known = false;
  bool anchor = false;         // learned, but held fixed: it defines the world frame
  TagCorners known_corners{Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()};
  PoseParams world_from_tag;

  TagCorners CornersInWorld() const;
};

// Joint covariance of the learned tags' poses after the final adjustment, in
// the tangent space of world_from_tag: per tag [rotation (3, a small
// rotation applied on the left, world frame), translation (3)], in the
// order of `ids`. Scaled by the residuals' estimated variance (a posteriori).
struct TagCovariance {
  std::vector<TagId> ids;
  Eigen::MatrixXd covariance;  // 6 * ids.size() square
};

// A scale bar as the result found it.
struct ScaleBarCheck {
  ScaleBar bar;
  double measured_m = 0;  // in the map as adjusted at the nominal tag sizes
  double sigma_m = 0;     // the map's own sigma of that length (0 without a covariance)
  double residual_m = 0;  // scaled length - certified length
};

// Where the map's scale comes from and how well it is known: the printed
// tag sizes (sigma_rel: the print tolerance, ReconstructorOptions::
// tag_size_sigma_rel) or the scale bars (scale_bars.h).
struct MapScale {
  std::string source = "tag sizes";  // or "scale bars"
  double scale = 1.0;                // applied to the scene adjusted at the nominal sizes
  double sigma_rel = 0.0;            // the scale's relative 1-sigma
  std::vector<ScaleBarCheck> bars;
  std::string note;                  // e.g. why the bars were not used
};

// Per-target figures of the result.
struct TargetStats {
  int track_length = 0;        // registered frames whose view of the tag is in the adjustment
  int outlier_views = 0;       // registered frames whose view of it was left out (TagObservation::outlier)
  double rms_px = 0;           // its corners' reprojection RMS over the track's frames
  bool known = false;
};

// Point ids of the result files: target corners are 4 * tag_id + corner + 1,
// feature point i (in feature_points' order) is kFirstFeaturePointId + i.
constexpr long long kFirstFeaturePointId = 100000000;

// What a finished reconstruction hands to the writers.
struct ReconstructionResult {
  CameraModel camera;
  std::vector<FrameState> frames;            // every frame given, registered or not
  std::map<TagId, MapTag> tags;
  std::map<TagId, TargetStats> target_stats;
  std::optional<TagCovariance> covariance;
  std::string covariance_note;               // why absent, when absent
  double reprojection_rms_px = 0;            // all observations of mapped tags in registered frames
  int observations = 0;
  int outlier_observations = 0;              // tag views left out (TagObservation::outlier)
  // With weighted corners: the corners' errors against the detector's
  // covariance, from the residuals (ReconstructorOptions::weight_corners).
  CornerNoiseModel corner_noise;
  int tags_remapped = 0;                     // learned tags mapped again while running (disagreed with the frames)
  std::map<std::string, int> pose_method_counts;  // "epnp", "sqpnp", "ippe", "fallback", ...
  std::optional<TagId> anchor_tag;           // the tag that fixes the world frame (no known map)
  std::map<TagId, std::string> unmapped_tags;  // seen but not mapped, with why
  MapScale scale;
  bool global_adjustment_converged = false;
  int window_solves_failed = 0;
  int frames_thinned = 0;  // frames whose tag views were given back (ReconstructorOptions::max_retained_frames)
  // Feature points in the last adjustment with the targets (its tie points,
  // ReconstructorOptions::tie_points_per_keyframe), and its time with the
  // others' refinement on the poses it adjusted.
  int points_adjusted = 0;
  double points_adjustment_s = 0;
  // How far the last adjustment with the points moved the cameras at them
  // (median, px), and how many times the points were triangulated again
  // from the adjusted poses.
  double points_shift_px = 0;
  int points_refits = 0;
  bool intrinsics_refined = false;           // `camera` is the adjusted one
  // With intrinsics_refined: fx and fy adjusted as one (the free fit's fx -
  // fy was within 3 sigma of 0: the data do not say the pixels are not square).
  bool square_pixels = false;
  // With intrinsics_refined: the covariance of fx, fy, cx, cy (pixels), k1
  // and k2 in the final adjustment (every pose and learned tag free; see
  // intrinsics_check.h); absent when it could not be computed.
  std::optional<Eigen::Matrix<double, 6, 6>> intrinsics_covariance;
  double global_adjustment_s = 0, covariance_s = 0;
  // Natural features triangulated from the final poses (empty with
  // --no-features); their ids in the result files start at kFirstFeaturePointId.
  std::vector<FeaturePoint> feature_points;

  PoseMap Poses() const;
  TargetCornerMap Targets() const;
};

}  // namespace tagsfm
