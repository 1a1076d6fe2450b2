#pragma once
// The per-frame photogrammetry engine on targets (the paper's stages 2, 3
// and 5): AddFrame takes one frame's tag detections and returns that frame's
// pose (or why it has none); Finish runs the final global adjustment and
// hands back the whole result. No I/O inside: `replay` and the live daemon
// both drive it with plain values.
#include <array>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <vector>

#include "tagsfm/capture/recording.h"
#include "tagsfm/detect/tag_detection.h"
#include "tagsfm/recon/bundle_adjuster.h"
#include "tagsfm/recon/corner_prediction.h"
#include "tagsfm/recon/pose_estimator.h"
#include "tagsfm/recon/reconstruction.h"

namespace tagsfm {

struct ReconstructorOptions {
  PoseEstimatorOptions pose;
  BundleAdjusterOptions ba;
  // A new tag enters the map once two of its views differ by this angle
  // (the planar ambiguity and its depth are then decided), or after
  // max_pending_views views whatever their angle.
  double min_tag_view_angle_deg = 3.0;
  int max_pending_views = 8;
  double max_tag_init_rms_px = 2.0;
  // A learned tag that is an outlier in this many registered frames in a
  // row (the frames' poses come from the other tags) is mapped again from
  // those views: a tag put into the map on the wrong side of its planar
  // ambiguity, or from views too alike, is otherwise left out of every
  // adjustment from then on and never mended.
  int remap_after_outlier_frames = 3;
  // Without a map: frames kept while waiting for two views that share two
  // tags from this angle apart; after that many, one view starts the map.
  int bootstrap_max_frames = 10;
  double bootstrap_min_angle_deg = 3.0;
  // A registered frame becomes a keyframe when it mapped a new tag, or when
  // it moved this fraction of the tags' median depth or turned this much
  // from every keyframe so far (a view already held is not taken again).
  double keyframe_min_translation_ratio = 0.05;
  double keyframe_min_rotation_deg = 5.0;
  bool final_adjustment = true;
  // The final adjustment takes every keyframe and, of the other frames with
  // tags, at most this many, spread evenly in time: beyond it every second
  // one gives back its tag views (its pose stays as registered live), so a
  // capture of hours holds bounded memory (2-5 kB a frame kept, ~200 bytes
  // one given back). Consecutive video frames are near-duplicate views; the
  // keyframes carry the geometry.
  int max_retained_frames = 5000;
  // Adjust the intrinsics too in the final adjustment (a camera calibrated
  // from the targets: pinhole, k1 k2 only).
  bool refine_intrinsics = false;
  // The printed tag size's relative 1-sigma (the printer's scale tolerance):
  // what the images cannot see, so it enters the reported sigma of every
  // length when the scale comes from the tags (no scale bars). 2e-4 is a
  // print checked with a calliper; an unchecked office print is ~1e-3.
  double tag_size_sigma_rel = 2e-4;
  // Each corner's residual weighted by the edge fit's covariance C of it
  // (TagDetection::corner_covariance) in the final adjustments. Its error is
  // taken as scale^2 C + floor^2, both measured from the residuals of the
  // first, unweighted adjustment (result.corner_noise: rendered walks have
  // a floor of ~0, a real room whose lens the model lacks one 10x the
  // fit's sigma, and its corners then count nearly the same); the floor is
  // at least corner_sigma_floor_px. Relative to a corner of
  // corner_sigma_reference_px plus the floor (a typical one: the rendered
  // walks' median corner error is 0.028 px), so that robust losses keep
  // their scale in pixels; its sigma held within 5x of the reference. The
  // live window and the first adjustment, after which the outliers are
  // chosen, count every corner the same: weighted, one precise tag that
  // disagreed with three others outvoted them (docs/recon.md).
  bool weight_corners = true;
  double corner_sigma_reference_px = 0.03;
  double corner_sigma_floor_px = 0.0;
  // The feature points' views are fitted on the targets' poses. When the
  // adjustment with the points moves the cameras at the points by more
  // than this (median, px: the refined views' noise), the targets alone
  // had left the poses inconsistent with the scene (a room of real photos:
  // 0.4 px across the epipolar lines), and the points are triangulated and
  // adjusted again from the adjusted poses, at most max_points_refits
  // times (swatbotics: 1,548 points, 1,981 after one refit, 2,091 after
  // two, 2,117 after three; docs/features.md).
  double points_refit_shift_px = 0.1;
  int max_points_refits = 2;
  // Tie points: the adjustment with the points takes, spread over each
  // keyframe's image, the points seen in most views until each keyframe
  // has about this many (0: every point); the others are then refined one
  // by one on the adjusted poses (feature/held_pose_refinement.h), on
  // points_threads threads (any number gives the same points). The poses
  // come out as from all the points, in a third of the time (the 1280x720
  // walk: 16,451 of 60,370 points, 0.54 s instead of 1.59; docs/features.md).
  int tie_points_per_keyframe = 3000;
  int points_threads = 2;

  Status Check() const;
};

// A frame registered, as a keyframe, while a later one was added: the views
// the bootstrap held back until the map could start.
struct EarlierKeyframe {
  FrameId frame = 0;
  Rigid3d cam_from_world;
  DetectionSet tags;  // its tags' ids and corners, as detected
};

struct FrameReport {
  FrameId frame = 0;
  bool registered = false;
  std::string reason;
  Rigid3d cam_from_world;
  PoseMethod method = PoseMethod::kNone;
  bool fell_back = false;
  double rms_px = 0;
  int tags_seen = 0;
  int tags_used = 0;      // mapped tags the pose was computed from
  std::vector<TagId> outlier_tags;  // of those, the tags whose corners disagreed with the pose (left out)
  int tags_added = 0;     // tags this frame put into the map
  std::vector<TagId> remapped_tags;  // mapped tags this frame put elsewhere (remap_after_outlier_frames)
  bool keyframe = false;
  size_t mapped_tags = 0;
  // Earlier frames that became keyframes while this one was added, in frame
  // order (the one keyframe rule: the feature stage takes them too).
  std::vector<EarlierKeyframe> earlier_keyframes;
};

class Reconstructor {
 public:
  // `known_map`: targets held fixed (a photogrammetry system's output); tags
  // outside it are learned as without a map.
  static Result<std::unique_ptr<Reconstructor>> Create(const CameraModel& camera, const TargetConfig& targets,
                                                      const std::optional<TargetCornerMap>& known_map,
                                                      const ReconstructorOptions& options);
  ~Reconstructor();
  Reconstructor(const Reconstructor&) = delete;
  Reconstructor& operator=(const Reconstructor&) = delete;

  FrameReport AddFrame(const DetectionSet& detections);
  // Natural-feature points from the final poses (the feature stage's
  // triangulation), for Finish to adjust with the targets.
  using PointTriangulation = std::function<std::vector<FeaturePoint>(const PoseMap&, const CameraModel&)>;

  // Registers what can still be registered against the final map, adjusts
  // everything together and returns the result. With `triangulate`, the
  // feature points from the adjusted poses then join a last adjustment with
  // the targets (which keep the datum and the scale). Call once.
  ReconstructionResult Finish(const PointTriangulation& triangulate = {});

  // Where the mapped tags will be in `frame` (a frame after the last one
  // added): the map projected with the pose extrapolated from the last two
  // registered frames (ProjectMappedTags, ExtrapolatePose). Empty before the
  // map exists, or when the last frame added was not registered (no pose to
  // go on).
  std::map<TagId, QuadCorners> PredictTagCorners(FrameId frame, const CornerPredictionOptions& options = {}) const;

  size_t mapped_tags() const { return tags_.size(); }
  // The mapped targets' corners in the world frame as they stand now (the
  // feature stage takes the depth range of a keyframe's scene from them).
  TargetCornerMap MappedTargetCorners() const;
  size_t frames() const { return frames_.size(); }

 private:
  Reconstructor(const CameraModel& camera, const TargetConfig& targets, const ReconstructorOptions& options);
  FrameState& MakeFrameState(const DetectionSet& detections);
  bool TryBootstrap(FrameState& frame);
  void StartMapFromOneView(FrameState& frame);
  void StartFromBuffer();
  void RegisterBuffered(const FrameState* except);
  // Finish's phases, in order.
  void MapWaitingTags();
  void RegisterLateFrames();
  std::vector<FrameState*> RegisteredFrames();
  void AdjustFirstAndRetry(std::vector<FrameState*>* registered);
  void AdjustFinally(const std::vector<FrameState*>& registered, ReconstructionResult* result);
  // The scale from targets.scale_bars (or the tags' print tolerance without them).
  void ApplyScale(std::vector<FrameState*>* registered, ReconstructionResult* result);
  // The feature points from the registered poses, adjusted with them, and
  // again from the adjusted poses while these move (points_refit_shift_px).
  void TriangulateAndAdjust(const std::vector<FrameState*>& registered, const PointTriangulation& triangulate,
                            ReconstructionResult* result);
  void AdjustWithPoints(const std::vector<FrameState*>& registered, std::vector<FeaturePoint>* points,
                        ReconstructionResult* result);
  // The scale bars fitted again on the map the points' adjustment left.
  void RefitScaleBars(std::vector<FrameState*>* registered, ReconstructionResult* result);
  // Every tag seen but not in the map, with why (ReconstructionResult::unmapped_tags).
  std::map<TagId, std::string> UnmappedTagReasons() const;
  void CollectReprojectionStatistics(const std::vector<FrameState*>& registered, ReconstructionResult* result) const;
  // Pose from the mapped tags it sees, then map new tags and adjust.
  void Register(FrameState& frame, bool adjust, FrameReport* report);
  // Register's steps: the frame's corners on mapped tags (with `adjust`,
  // its pending tags mapped first when none is); the pose from them, checked
  // against this frame's own corner noise when the usual limit refuses it.
  struct FrameCorrespondences;
  FrameCorrespondences MappedCorners(FrameState& frame, bool adjust, FrameReport* report);
  PoseResult SolveFramePose(const FrameState& frame, const FrameCorrespondences& mapped);
  int MapPendingTags(FrameState& frame, std::vector<TagId>* added);
  // Maps the frame's pending tags from the views they have, however few.
  std::vector<TagId> MapPendingTagsNow(const FrameState& frame);
  // Maps again the learned tags that this frame and the ones before it
  // found to be outliers; returns those that moved.
  std::vector<TagId> RemapDisagreeingTags(FrameState& frame);
  bool IsKeyframe(const FrameState& frame, bool added_tags) const;
  // Keeps the newest frame's tag views or gives them back, and halves the
  // frames kept when they exceed max_retained_frames (ThinFrames).
  void RetainOrThin(size_t index);
  // A frame whose views the map still waits on (bootstrap, pending tags, outlier runs).
  bool IsHeld(const FrameState& frame) const;
  void GiveBackViews(FrameState* frame);
  // Makes `frame` a keyframe: into the window (with the tags it just
  // mapped, `added`), then the window solved and its solution applied.
  void AddKeyframe(FrameState& frame, const std::vector<TagId>& added);
  void SolveWindow();
  FrameState* FindKeyframe(FrameId id);
  std::optional<Rigid3d> PreviousPose(const FrameState& frame) const;
  void CountMethod(const FrameState& frame);
  // The frame's corner noise from its tags' shapes (MeasureCornerNoisePx).
  double MeasureFrameNoisePx(const FrameState& frame) const;
  void RememberNoise(double sigma_px);
  // A new tag's fit is accepted within this RMS: the fixed limit, or more
  // when the measured corner noise asks for it.
  double TagInitLimitPx() const;
  // Each corner of `obs` minus `tag`'s projection from `cam_from_world`, in
  // normalised coordinates; infinite for a corner behind the camera.
  static std::array<Eigen::Vector2d, 4> NormalizedCornerErrors(const Rigid3d& cam_from_world, const MapTag& tag,
                                                               const TagObservation& obs);
  // Marks the tag views that disagree with the current poses and map
  // (TagObservation::outlier); returns how many.
  int FlagOutlierObservations(const std::vector<FrameState*>& frames);
  CornerNoiseModel EstimateCornerNoise(const std::vector<FrameState*>& registered) const;
  // Each view's corner weights from its covariance and the estimated floor.
  void SetWeights(const std::vector<FrameState*>& registered, ReconstructionResult* result);

  CameraModel camera_;
  TargetConfig targets_;
  ReconstructorOptions options_;
  // The final adjustment found the pixels square (fy tied to fx in it and in
  // the adjustment with the feature points).
  bool square_pixels_ = false;
  double fx_, fy_;
  std::deque<FrameState> frames_;                 // stable addresses: the adjuster points into them
  std::map<TagId, MapTag> tags_;
  std::map<TagId, std::vector<FrameState*>> pending_;  // unmapped tags' registered views
  // Learned tags' latest run of registered frames in which they were outliers.
  std::map<TagId, std::vector<FrameState*>> outlier_runs_;
  int tags_remapped_ = 0;
  // Frames kept in the final adjustment besides the keyframes: every
  // retain_stride_-th frame, retained_ of them now; frames_thinned_ given back.
  size_t retain_stride_ = 1;
  size_t retained_ = 0;
  int frames_thinned_ = 0;
  std::map<TagId, std::string> unmapped_reasons_;  // why a waiting tag was not mapped at Finish
  std::vector<FrameState*> bootstrap_buffer_;
  bool started_ = false;                          // the map exists (known, or bootstrapped)
  std::optional<TagId> anchor_;
  const FrameState* last_registered_ = nullptr;
  std::vector<FrameState*> keyframes_;   // in the order chosen
  std::unique_ptr<SlidingWindowBundleAdjuster> window_;
  std::map<std::string, int> method_counts_;
  // Corner noise per axis measured on frames whose pose failed the fixed
  // limits (0: none yet); the pose checks follow it.
  std::deque<double> noise_measurements_;
  double corner_noise_px_ = 0;
};

}  // namespace tagsfm
