#pragma once
// Least-squares matching (Gruen 1985), the photogrammetric refinement of a
// matched point: a small patch of a reference image round a feature is
// fitted to a second image under an affine warp and a brightness/contrast
// change, by Gauss-Newton on the grey-value differences. SIFT puts a
// feature within ~0.3-0.4 px of where the same surface point is in another
// view; the fit brings the views of a track to a few hundredths of a pixel
// of one another, which is what the depth of a point from narrow rays needs.
#include <optional>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "tagsfm/core/result.h"

namespace tagsfm {

struct PatchRefinementOptions {
  int half_window = 7;     // the patch is (2 h + 1)^2 reference pixels
  int max_iterations = 12;
  // Stop when the centre moves less than this: the fit's steps shrink 3-4x
  // an iteration, so what is left is ~0.006 px, a fifth of a good fit's
  // own sigma and a sixteenth of the 0.1 px the triangulation weighs a fit
  // at least (docs/features.md: 0.01 took 10-15 % more fit time for fewer
  // points, 0.03 lost accuracy on the dim walk).
  double converged_px = 0.02;
  // A fit out of iterations still counts when its last step was under this
  // fraction of its own sigma (the classical adjustment's rule: corrections
  // below their precision), the step then added to that sigma. On a noisy
  // or plain patch Gauss-Newton keeps stepping by hundredths of a pixel
  // about a minimum its noise leaves uncertain by tenths, and never
  // reaches converged_px (docs/features.md). 0: converged_px alone.
  double converged_sigma_fraction = 0.25;
  // The fit steps on every other pixel of every other row (a quarter of
  // the work, the same reach) until a step is shorter than this, then on
  // every pixel; of those first steps only the one that ends them counts
  // against max_iterations. Most of
  // the fits a triangulation tries are refused, and they are refused
  // within a few such steps (docs/features.md). 0: every pixel throughout.
  double sparse_until_px = 0.1;
  // Furthest the fitted centre may move from where it started: beyond, the
  // match was wrong or the fit ran off along an edge.
  double max_shift_px = 2.0;
  // Least normalised cross-correlation of the fitted patches: lower is
  // a different surface, an occlusion or a specular spot.
  double min_correlation = 0.8;
  // Largest predicted standard deviation of the fitted centre (along its
  // worse axis, from the fit's residual and normal matrix): an edge or a
  // flat patch is located only along one axis or not at all.
  double max_sigma_px = 0.1;
  // Fit a view that sees the patch 1.4x larger or smaller than the
  // reference does (the predicted affine's scale) on the image halved, up
  // to max_level times (cv::pyrDown), that sees it at the reference's
  // scale, or the reference on the halved one: otherwise one patch is
  // sampled sparser than its pixels (aliased) and looks sharper than the
  // other. The shift and sigma limits then count that level's pixels; the
  // fit comes back in full-image pixels, its sigma with it.
  bool balance_scale = true;
  int max_level = 3;
  // A track whose views do not fit its reference (fewer than two left) is
  // fitted again to the next view nearest the mean viewing direction, up to
  // this many references in all; kept that way with three views or more
  // (track_refinement.h).
  int reference_attempts = 2;
  // A view whose fit is refused from the warp of a plane facing the
  // cameras is fitted again from planes tilted by 1, 2, ... up to
  // tilt_retries times tilt_step_deg each way, nearest first, in the plane
  // of its own and the reference's rays (the tilt that changes the warp
  // between them); the first fit accepted counts (track_refinement.h). A
  // wall seen obliquely from two sides is foreshortened differently in the
  // two views, and from the facing plane's warp the fit runs off. Each
  // retry is held to every check of the first fit. 0: no retries.
  int tilt_retries = 2;
  double tilt_step_deg = 30.0;

  Status Check() const;  // names the wrong field
};

// Where the reference patch lies in the other image: its centre and the
// affine map of offsets from the reference centre (target offset = A *
// reference offset).
struct PatchWarp {
  Eigen::Vector2d centre = Eigen::Vector2d::Zero();
  Eigen::Matrix2d affine = Eigen::Matrix2d::Identity();
};

// A line the fitted centre must stay on (through the start's centre): the
// epipolar line of the reference pixel when the poses are known. The fit
// then finds where along it the patch lies, which an edge crossing the line
// fixes although it leaves a free fit sliding along itself.
struct PatchLine {
  Eigen::Vector2d direction = Eigen::Vector2d::UnitX();  // unit, target image
  // How far the true line may lie across itself, px (the poses' and the
  // lens' error): enters the fit's sigma through the patch's coupling of
  // the two directions.
  double across_sigma_px = 0;
};

struct PatchFit {
  PatchWarp warp;
  double correlation = 0;  // normalised cross-correlation at the fit
  double sigma_px = 0;     // predicted standard deviation of warp.centre: worse axis, or along the line
  int iterations = 0;      // steps on every pixel, and the sparse step that ended sparse_until_px's
};

// Fits the patch of `reference` (8-bit grey) round `reference_pixel` into
// `target` (8-bit grey), starting from `start`. Pixels in OpenCV's convention
// (centres at integers). nullopt when the patch leaves either image, the
// fit does not converge, or it fails one of the options' checks.
std::optional<PatchFit> RefinePatch(const cv::Mat& reference, const Eigen::Vector2d& reference_pixel, const cv::Mat& target,
                                    const PatchWarp& start, const PatchRefinementOptions& options,
                                    const std::optional<PatchLine>& line = std::nullopt);

}  // namespace tagsfm
