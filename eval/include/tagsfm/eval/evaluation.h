#pragma once
// Scoring a replay's results (OUT/) against a recording's ground truth
// (REC/ground_truth/), as the paper does in section 4:
//   eq. 1  reprojection error: the true target corners projected with the
//          estimated pose vs with the true pose, pixels (mean per frame);
//   eq. 2  rotational error ||q_est - q_true|| / ||q_true||, quaternions
//          sign-aligned (also as an angle in degrees);
//   eq. 3  positional error of the camera centres, metres;
// plus target corner errors and the distance of every cloud point to the
// true surfaces, and for the natural-feature points alone (tagsfm's
// features.csv, or a COLMAP model's points) the shares within 1, 2 and 5 mm
// of them and their mean stored reprojection error. Each is given as is, after a best-fit rigid alignment and
// after a best-fit similarity alignment (for results without metric scale
// or in another world frame).
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "tagsfm/core/camera_model.h"
#include "tagsfm/core/csv_formats.h"
#include "tagsfm/eval/scene_geometry.h"
#include "tagsfm/eval/similarity.h"
#include "tagsfm/recon/measurement.h"

namespace tagsfm::eval {

struct Stats {
  int count = 0;
  double mean = 0, median = 0, p95 = 0, max = 0, rms = 0;
  static Stats Of(std::vector<double> values);
};

struct FrameError {
  FrameId frame = 0;
  std::optional<double> reprojection_px;  // absent without intrinsics or visible corners
  double rotation_rel = 0;
  double rotation_deg = 0;
  double position_m = 0;
};

struct PoseErrors {
  std::vector<FrameError> frames;
  Stats reprojection_px, rotation_rel, rotation_deg, position_m;
};

struct TargetErrors {
  int common_tags = 0;
  Stats corner_error_m;  // rms and max are what matter
};

// A natural-feature point with the reprojection error its file stores:
// tagsfm's features.csv the RMS over the point's observations, COLMAP's
// points3D.txt (ERROR) the mean. RMS >= mean, so comparing the two is
// conservative for tagsfm.
struct ScoredPoint {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  double reprojection_px = 0;
};

// How close the feature points come to the true surfaces.
struct SurfaceShares {
  Stats distance_m;
  double within_1mm = 0, within_2mm = 0, within_5mm = 0;  // shares of the points, 0-1 (distance <= limit)
};

// One way of putting the estimate into the true frame.
struct AlignedErrors {
  std::string name;  // "as_is", "rigid", "similarity"
  Sim3d true_from_est;
  std::optional<PoseErrors> poses;
  std::optional<TargetErrors> targets;
  std::optional<Stats> cloud_distance_m;
  std::optional<SurfaceShares> feature_points;  // with surfaces and at least one feature point
};

// One test length in the style of VDI/VDE 2634-1: the distance between two
// tags' centres as measured (no alignment: a length needs none) against the
// true one; sigma from the result's covariance (targets_cov.csv) when given.
struct LengthError {
  TagId a = -1, b = -1;
  double true_length_m = 0, measured_length_m = 0;
  double error_m = 0;              // measured - true (the length-measurement error E)
  std::optional<double> sigma_m;
};

struct LengthErrors {
  std::vector<LengthError> pairs;  // every pair of tags in both maps, shortest first
  Stats abs_error_m;
  // error / sigma over the pairs with a sigma above zero: a sigma that
  // describes the error has mean ~0 and standard deviation ~1.
  int normalized_count = 0;
  double normalized_mean = 0, normalized_std = 0;
  double beyond_3_sigma = 0;       // share of those pairs, 0-1
  double error_per_length_ppm = 0; // least-squares slope of E against L (a scale error shows here)
  // The same slope with each pair weighted by 1 / sigma^2 of its length from
  // the covariance alone (the common scale term left out: it is the same
  // for every pair): the map's scale as its precision sees it. One tag seen
  // in a few poor views moves the plain slope, and a similarity fit over
  // all corners, by its whole error; here it counts by its sigma. Absent
  // without a covariance.
  std::optional<double> weighted_error_per_length_ppm;
};

// The self-survey's precision: the estimated map against the true targets
// as a fraction of the scene's size (the true corners' bounding-box diagonal).
struct MapPrecision {
  double scene_size_m = 0;
  double rigid_rms_m = 0, similarity_rms_m = 0;  // corner RMS after each alignment
  double rigid_ratio = 0, similarity_ratio = 0;  // scene size / RMS (1:N)
  double scale_error_ppm = 0;                    // the similarity fit's scale - 1
};

// What a comparison needs, already loaded; absent parts are simply skipped.
struct EvaluationInput {
  std::optional<CameraModel> camera;
  std::optional<PoseMap> true_poses, estimated_poses;
  std::optional<TargetCornerMap> true_targets, estimated_targets;
  std::optional<std::vector<SurfaceRectangle>> surfaces;
  std::optional<std::vector<Eigen::Vector3d>> cloud;
  std::optional<std::vector<ScoredPoint>> feature_points;
  std::optional<TagCovariance> target_covariance;  // the result's targets_cov.csv
  double scale_sigma_rel = 0;                      // report.json's scale.sigma_rel (0 when absent)
};

struct Evaluation {
  int ground_truth_frames = 0;
  int registered_frames = 0;    // estimated poses of ground-truth frames
  int unregistered_frames = 0;  // ground-truth frames without an estimated pose
  int unknown_frames = 0;       // estimated poses of frames the truth lacks
  std::vector<TagId> missing_tags, unknown_tags;
  int cloud_points = 0;
  int feature_points = 0;
  std::optional<double> feature_mean_reprojection_px;  // mean over the feature points of their stored error
  std::string alignment_source;  // "target_corners", "camera_centres" or "none"
  int alignment_correspondences = 0;
  std::vector<AlignedErrors> variants;  // as_is, then rigid and similarity when alignable
  std::optional<MapPrecision> map;      // with target-corner alignment
  std::optional<LengthErrors> lengths;  // with two or more tags in both maps
};

Evaluation Evaluate(const EvaluationInput& input);

// The length errors of every pair of tags common to both maps.
LengthErrors CompareLengths(const TargetCornerMap& truth, const TargetCornerMap& estimate,
                            const std::optional<TagCovariance>& covariance, double scale_sigma_rel = 0);

// Loads OUT/ and REC/ (missing optional files are reported as absent, a
// malformed one is an error naming it), evaluates, and renders the JSON that
// `tagsfm evaluate` prints. OUT may also be a COLMAP text model (a folder
// with images.txt and points3D.txt): its images are matched to REC's frames
// by file name, its points are the cloud and the feature points, and it is
// aligned by the camera centres (it has no targets).
Result<std::string> EvaluateDirectoriesJson(const std::filesystem::path& out, const std::filesystem::path& rec);

}  // namespace tagsfm::eval
