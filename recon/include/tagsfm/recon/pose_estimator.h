#pragma once
// The camera pose of one frame from 2D-3D correspondences of target corners:
// EPnP on all correspondences (the paper's solver; tag ids make outliers
// rare), then a robust Levenberg-Marquardt refinement. Every pose is checked
// (reprojection RMS, cheirality, agreement with the previous frame); when
// EPnP's fails, or the points are nearly coplanar (where EPnP + LM was
// measured to land 25-40 degrees off), SQPnP and IPPE are tried too and the
// best checked pose wins; only when none fits every correspondence does EPnP
// run inside RANSAC (the fallback). Degenerate input gives an unregistered
// result with a reason, never a wild pose.
#include <array>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "tagsfm/core/result.h"
#include "tagsfm/core/rigid3d.h"

namespace tagsfm {

enum class PoseMethod { kNone, kEpnp, kSqpnp, kIppe };
const char* PoseMethodName(PoseMethod method);

struct PoseEstimatorOptions {
  double ransac_threshold_px = 4.0;   // inlier threshold of RANSAC, and the most the final inlier set allows
  int ransac_iterations = 200;
  double ransac_confidence = 0.999;
  double max_rms_px = 2.0;            // a checked pose reprojects its inliers within this RMS
  // The corners' noise per axis as measured (MeasureCornerNoisePx), 0 when
  // not known. The checks follow it where it exceeds the fixed limits: the
  // RMS limit becomes max(max_rms_px, rms_sigmas * sqrt(2) * sigma) (the 2D
  // error of a right pose is ~sqrt(2) sigma), the inlier threshold
  // max(ransac_threshold_px, 4 * sigma) (a 2D Gaussian error exceeds 4 sigma
  // with probability 3e-4), the Huber threshold max(huber_px, 2 * sigma).
  double corner_sigma_px = 0.0;
  double rms_sigmas = 2.0;
  // Within the inlier threshold, a corner whose error exceeds this many
  // robust sigmas of the pose's own errors (median based), and at least
  // min_outlier_px, is an outlier too: a corner of a tag cut by the image
  // border was measured 3 px off among 0.02 px ones and tilted a pose 0.16
  // degrees.
  double outlier_sigmas = 6.0;
  double min_outlier_px = 1.0;
  double min_inlier_ratio = 0.5;      // of the correspondences given
  // Agreement with the previous frame: a pose that rotated more than this
  // loses to a candidate that did not (when both pass the other checks).
  double max_rotation_jump_deg = 30.0;
  // Points whose spread's smallest axis is below this fraction of the largest
  // count as nearly coplanar: SQPnP and IPPE are consulted as well.
  double planarity_ratio = 0.1;
  double huber_px = 1.0;              // robust loss of the refinement
  int refine_iterations = 20;

  Status Check() const;
};

struct PoseResult {
  bool registered = false;
  std::string reason;               // why not, when not registered
  Rigid3d cam_from_world;
  std::vector<int> inliers;         // indices into the correspondences
  double rms_px = 0.0;              // over the inliers
  PoseMethod method = PoseMethod::kNone;
  bool fell_back = false;           // EPnP's pose failed a check and another solver's was taken
};

// points_in_world[i] is seen at normalized[i] (undistorted normalised image
// coordinates, CameraModel::PixelsToNormalized). fx, fy convert normalised
// errors to pixels. `previous` is the last registered frame's pose, if any.
PoseResult EstimatePose(const std::vector<Eigen::Vector3d>& points_in_world,
                        const std::vector<Eigen::Vector2d>& normalized, double fx, double fy,
                        const std::optional<Rigid3d>& previous, const PoseEstimatorOptions& options);

// Refines a pose on fixed points `use` with a Huber loss on the pixel error
// (huber_px <= 0: plain least squares), Levenberg-Marquardt; returns the
// refined pose (a non-finite `initial`, or one that puts a point behind the
// camera, comes back unchanged). `final_cost`: half the sum of the loss.
Rigid3d RefinePose(const std::vector<Eigen::Vector3d>& points_in_world, const std::vector<Eigen::Vector2d>& normalized,
                   const std::vector<int>& use, double fx, double fy, const Rigid3d& initial, double huber_px,
                   int max_iterations, double* final_cost = nullptr);

// The corners' noise per axis in pixels, measured from the tags' shapes
// alone: each tag's own pose (known size, 6 parameters) fits its 8 corner
// coordinates with 2 to spare, so its squared residual is sigma^2 times a
// chi-square of 2 degrees of freedom, whose median is 2 ln 2. The median over
// the tags makes it robust to a few bad ones. 0 when no tag gives a pose.
double MeasureCornerNoisePx(const std::vector<std::array<Eigen::Vector2d, 4>>& tags_normalized,
                            const std::vector<double>& sizes_m, double fx, double fy);

// Both IPPE solutions (planar pose ambiguity) of cam_from_tag for a square
// tag's four corners seen at `normalized`, each refined (LM) and ranked by
// its reprojection error after refinement, best first. Empty on failure.
std::vector<Rigid3d> TagPoseCandidates(const std::array<Eigen::Vector2d, 4>& normalized, double size_m);

}  // namespace tagsfm
