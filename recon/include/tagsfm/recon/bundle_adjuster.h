#pragma once
// Bundle adjustment of target corners (Ceres): a sliding window over the
// last keyframes while frames arrive, and one global adjustment at the end.
// Learned tags are rigid squares of known size (pose parameters, size
// constant); known-map tags are held fixed; the anchor tag, which defines the
// world when there is no map, is held fixed too.
#include <array>
#include <deque>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "tagsfm/core/result.h"
#include "tagsfm/recon/reconstruction.h"

namespace ceres {
class Problem;
}

namespace tagsfm {

struct BundleAdjusterOptions {
  int window_keyframes = 8;       // K: keyframes in the sliding window
  int window_iterations = 6;      // LM iterations per window solve (bounds per-frame time)
  int global_iterations = 100;
  double huber_px = 1.0;          // robust loss scale
  // Threads of the global adjustments. One by default: Ceres' threaded
  // Schur elimination adds in the order the threads finish, so the same
  // recording gave poses 1e-6 m apart and a few feature points more or
  // less from run to run (ceres-solver issue 664); with one, replay, live
  // and a second replay agree bit for bit. More is faster on an idle
  // machine, at that price.
  int global_threads = 1;
  // Threads of a window solve. One: the solve is small (8 keyframes, ~35
  // tags: a 6-dof block each, the tags eliminated), and on a 2-core rig the
  // detector's threads run beside it; measured side by side on the shared
  // 2-core machine, no-map p95 4.5-4.9 ms with 1 thread, 4.7-5.9 ms with 2.
  int window_threads = 1;
  bool compute_covariance = true; // of the learned tags, after the global adjustment
  // Global adjustments: each tag corner whitened by its observation's
  // weights (TagObservation::weight_*, the edge fit's covariance); off,
  // every corner counts the same. The window never weights: see
  // ReconstructorOptions::weight_corners for why.
  bool weight_corners = false;
  // With the intrinsics adjusted: fy held equal to fx (SquarePixelTie). The
  // reconstructor decides it from the data (Reconstructor::AdjustFinally).
  bool square_pixels = false;

  Status Check() const;
};

// The window keeps its own copies of its keyframes' poses, their tag views
// and the learned tags it adjusts, keyed by frame and tag id: the caller's
// containers may move, and nothing changes in them behind its back. Solve
// hands the adjusted values back (WindowSolution) for the caller to apply.
struct WindowSolution {
  bool solved = false;  // false: skipped, or failed (nothing to apply)
  std::vector<std::pair<FrameId, PoseParams>> cam_from_world;
  std::vector<std::pair<TagId, PoseParams>> world_from_tag;  // the learned tags in the window
};

class SlidingWindowBundleAdjuster {
 public:
  SlidingWindowBundleAdjuster(const BundleAdjusterOptions& options, double fx, double fy);
  ~SlidingWindowBundleAdjuster();
  SlidingWindowBundleAdjuster(const SlidingWindowBundleAdjuster&) = delete;
  SlidingWindowBundleAdjuster& operator=(const SlidingWindowBundleAdjuster&) = delete;

  // Adds a registered keyframe with a residual for each corner of each tag
  // of `tags` it sees (its outlier views left out); the oldest keyframe
  // leaves when the window is full.
  void AddKeyframe(const FrameState& frame, const std::map<TagId, MapTag>& tags);
  // A tag just put into the map: adds the window keyframes' views of it.
  void AddTag(const MapTag& tag);
  // A tag mapped again (Reconstructor's remapping) from the views of the
  // frames `fitted`: its residuals leave the window; the window keyframes
  // among `fitted` add theirs back, the others' views of it become outliers
  // (they saw it where it no longer is, or would pull it back to where it
  // was mapped wrong). Returns those keyframes, for the caller to mark.
  std::vector<FrameId> ReplaceTag(const MapTag& tag, const std::vector<FrameId>& fitted);
  // Solves the window (a few LM iterations). Skipped when no tag in the
  // window is free (poses alone are what PnP already refined). A failed
  // solve leaves the window as it was, and is counted.
  WindowSolution Solve();
  int failed_solves() const { return failed_solves_; }
  size_t keyframes() const { return window_.size(); }
  size_t residual_blocks() const;

 private:
  struct Keyframe {
    FrameId frame = 0;
    PoseParams cam_from_world;          // a parameter block of the problem
    std::vector<TagObservation> views;  // all its tag views, as added
    std::vector<TagId> in_problem;      // the tags whose residuals it holds
  };
  void AddObservation(Keyframe* keyframe, const TagObservation& obs, const MapTag& tag);
  void RemoveOldest();
  void HoldOldestFixed();

  BundleAdjusterOptions options_;
  double fx_, fy_;
  std::unique_ptr<ceres::Problem> problem_;
  std::deque<Keyframe> window_;                 // oldest first; stable addresses (the problem points into them)
  std::map<TagId, MapTag> learned_tags_;        // copies of the learned tags with residuals in the window
  std::map<TagId, int> residuals_per_tag_;
  int failed_solves_ = 0;
};

struct GlobalAdjustmentSummary {
  bool converged = false;
  int iterations = 0;
  double initial_rms_px = 0, final_rms_px = 0;
  double solve_s = 0, covariance_s = 0;
  std::optional<TagCovariance> covariance;
  std::string covariance_note;
  // With the intrinsics adjusted: their covariance, in the order fx, fy,
  // cx, cy (pixels), k1, k2.
  std::optional<Eigen::Matrix<double, 6, 6>> intrinsics_covariance;
};

// Natural-feature points adjusted with the poses and tags (the hybrid): the
// targets keep the datum and the metric scale, the points add their rays.
struct AdjustedPoint {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();             // world, metres; adjusted in place
  std::vector<std::pair<FrameId, Eigen::Vector2d>> observations;  // frame, pixel (distorted)
};
struct PointTerms {
  std::vector<AdjustedPoint>* points = nullptr;
  const CameraModel* camera = nullptr;  // undistorts the observations
  // A point residual's weight against a target corner's: sigma_corner /
  // sigma_point, so that each counts by its own precision (SIFT keypoints
  // are ~10x noisier than the edge-fit corners).
  double weight = 1.0;
  double huber_px = 1.0;  // robust scale, in the points' own pixels
};

// Adjusts every registered frame's pose and every learned tag together, and
// the points of `points` when given. With `refine_camera`, the intrinsics
// (fx, fy, cx, cy, k1, k2: a pinhole camera calibrated from the targets) are
// adjusted too, in pixel space, and written back.
GlobalAdjustmentSummary AdjustGlobally(const std::vector<FrameState*>& frames, std::map<TagId, MapTag>* tags,
                                       double fx, double fy, const BundleAdjusterOptions& options,
                                       CameraModel* refine_camera = nullptr, const PointTerms* points = nullptr);

// A diagnostic of the known-size model: the same adjustment with every
// learned tag's four corners as free 3D points (the anchor's held fixed, which
// keeps the scale), starting from the squares. Returns each learned tag's
// four edge lengths once relaxed; the poses and tags given are not changed.
std::map<TagId, std::array<double, 4>> RelaxedTagEdgeLengths(const std::vector<FrameState*>& frames,
                                                             const std::map<TagId, MapTag>& tags, double fx,
                                                             double fy, const BundleAdjusterOptions& options);

}  // namespace tagsfm
