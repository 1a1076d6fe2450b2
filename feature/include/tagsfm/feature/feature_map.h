#pragma once
// Feature tracks over every keyframe that sees the same part of the scene,
// not only the previous one: each new keyframe is matched (guided by the
// known poses, guided_matcher.h) against the earlier keyframes whose view
// overlaps its own, nearest in viewpoint first, and the matches are merged
// into tracks by a union-find. A feature seen again after a gap, or from
// the other side of a photo set, continues its track.
#include <map>
#include <utility>
#include <vector>

#include "tagsfm/core/camera_model.h"
#include "tagsfm/core/csv_formats.h"
#include "tagsfm/core/result.h"
#include "tagsfm/core/rigid3d.h"
#include "tagsfm/feature/feature_extractor.h"
#include "tagsfm/feature/feature_triangulation.h"
#include "tagsfm/feature/guided_matcher.h"
#include "tagsfm/feature/patch_refinement.h"
#include "tagsfm/feature/track_triangulation.h"

namespace tagsfm {

struct FeatureMapOptions {
  GuidedMatcherOptions matcher;
  // The triangulation of the tracks (with `refine`, the first pass, minus
  // its sigma filter, and the final one, with refined_feature_sigma_px).
  TrackTriangulationOptions triangulation;
  // Least-squares matching of every view of a track to a reference view
  // before the final triangulation (track_refinement.h); a first
  // triangulation of the SIFT pixels predicts the warps.
  bool refine = true;
  PatchRefinementOptions refinement;
  // With `refine`, the first pass's limit on a track's RMS reprojection at
  // its SIFT pixels, px. That pass only predicts the warps; a track whose
  // views all lie within triangulation.max_view_error_px (2 px, the fits'
  // reach refinement.max_shift_px) goes to the fits, which, with the final
  // pass's own limit, judge its point. At the final pass's 1 px it refused
  // tracks the fits would keep: swatbotics 4,067 -> 4,659 points, the
  // rendered walks as accurate or more (docs/features.md).
  double first_pass_max_reprojection_rms_px = 2.0;
  // The refined views' localisation noise, px, for the final pass's
  // predicted-sigma filter and covariance floor (measured in
  // docs/features.md).
  double refined_feature_sigma_px = 0.1;
  // A view whose fit is refused stays in its track at the SIFT pixel, with
  // the first pass's noise (triangulation.feature_sigma_px): it weighs less
  // and the predicted-sigma filter judges the point with it; a track with
  // no fit at all needs three views (track_refinement.h). Off by default:
  // on real photos 16-40 % more points, on the rendered box walk 0.6 % more
  // at 1.1 points less of the share within 2 mm (docs/features.md).
  bool keep_unrefined_views = false;
  // A view whose free fit is refused is fitted again along its reference
  // pixel's epipolar line (track_refinement.h), with the lines' error
  // measured from the free fits (FeatureTriangulationStats). On the room
  // walk of real photos (edges of doors and frames) 1.5x the points, on the
  // rendered box walk 1 % more (docs/features.md).
  bool epipolar_fallback = true;
  // With epipolar_fallback, a fit is refused above refinement.max_sigma_px
  // or above this many times the lines' measured error, whichever is
  // larger: where the poses and the lens put every view that far off the
  // scene, a view located better from its grey values is no more accurate,
  // and one located to that error at most is no more than sqrt 2 worse than
  // the best. Rendered scenes (lines' error 0.05-0.07 px) keep the fixed
  // limit; real photo sets (0.2-0.4 px) get theirs (docs/features.md).
  // 0: the fixed limit everywhere.
  double max_fit_sigma_per_epipolar_sigma = 1.0;
  int max_neighbours = 8;  // earlier keyframes a new one is matched with, most overlapping first
  // Share of the new keyframe's view (a grid of rays at its typical scene
  // depth) that must fall inside an earlier keyframe's image.
  double min_overlap = 0.2;
  // Largest angle between the two cameras' rays to the overlapping part of
  // the scene: beyond, SIFT descriptors no longer match (and would only
  // yield wrong matches).
  double max_view_angle_deg = 60.0;
  // Rematch: a pair of keyframes is matched again when the final poses and
  // camera move one's view of the scene in the other's image across the
  // epipolar line by more than this, pixels (at the worst of its sample
  // rays); the others keep their matches. Twice the default band's
  // half-width: box walks' pairs moved by up to 4 px, and matching them
  // again added 0.15-0.4 % points for 1.3x the run time; a room walk's live
  // map moved them by 7-970 px, and matching again added 78 %
  // (docs/features.md).
  double rematch_shift_px = 4.0;

  Status Check() const;  // names the wrong field
};

// What adding one keyframe did.
struct KeyframeMatchStats {
  FrameId frame = 0;
  std::vector<FrameId> matched_with;  // the earlier keyframes matched, most overlapping first
  int matches = 0;                    // guided matches over all of them
  int tracks_continued = 0;           // new features that joined a track of 2+ earlier views
  int tracks_started = 0;             // new features that started a track with earlier single features
  int tracks_merged = 0;              // two tracks of 2+ views joined through the new keyframe
  int conflicts = 0;                  // matches refused: they would put two features of one keyframe in a track
  int pairs_reused = 0;               // Rematch: pairs whose earlier matches were kept, not matched again
};

class FeatureMap {
 public:
  // `camera`: the intrinsics the keyframes are undistorted with for matching.
  static Result<FeatureMap> Create(const CameraModel& camera, const FeatureMapOptions& options);

  // Adds a keyframe seen from `cam_from_world` with its scene in `depth` and
  // matches it with the earlier ones that overlap it, one pair per thread
  // (the tracks are the same for any number of `threads`). An error (and no
  // change) for a frame already added or bad features / depth range.
  Result<KeyframeMatchStats> AddKeyframe(KeyframeFeatures features, const Rigid3d& cam_from_world, const DepthRange& depth,
                                         int threads = 1);

  // Builds the tracks again, in the order the keyframes were added, from
  // `cam_from_world` (the final poses) and `camera` (refined intrinsics): the
  // live poses that guided the first matching are less accurate, and the
  // epipolar band is a few pixels wide. Pairs of keyframes whose relative
  // geometry moved less than rematch_shift_px keep their matches; the others
  // are matched again. Keyframes without a pose here are left out. Returns
  // how many keyframes were matched again with at least one earlier one.
  Result<int> Rematch(const PoseMap& cam_from_world, const CameraModel& camera, int threads = 1);

  // Tracks of two or more views, each view's feature index and pixel.
  std::vector<FeatureTrack> Tracks() const;
  // Points of every track from the final poses: with options.refine, the
  // tracks' views are refined by least-squares matching first. The same
  // points for any number of `threads`.
  std::vector<FeaturePoint> Triangulate(const PoseMap& cam_from_world, const CameraModel& camera, int threads = 1,
                                        FeatureTriangulationStats* stats = nullptr) const;
  // The SIFT pixels triangulated, without the refinement and its filter: a
  // coarse cloud at a small part of the cost (the live cloud's).
  std::vector<FeaturePoint> TriangulateCoarse(const PoseMap& cam_from_world, const CameraModel& camera) const;

  int keyframes() const { return static_cast<int>(keyframes_.size()); }
  const PosedKeyframe& keyframe(int index) const { return keyframes_[static_cast<size_t>(index)]; }
  const FeatureMapOptions& options() const { return options_; }

 private:
  FeatureMap(const CameraModel& camera, const FeatureMapOptions& options);
  // Matches earlier keyframes' matches that Rematch keeps, by (new, earlier) frame.
  using KeptMatches = std::map<std::pair<FrameId, FrameId>, std::vector<FeatureMatch>>;
  // Matches the last keyframe added with the earlier ones that overlap it
  // (taking a pair's matches from `kept` when there), on `threads` threads.
  KeyframeMatchStats MatchLastKeyframe(KeptMatches* kept, int threads);
  void MergeMatches(int first_new, int earlier, const std::vector<FeatureMatch>& matches, KeyframeMatchStats* stats);
  // Pixels by which the final poses and camera (final_map's) move a's view of
  // its scene (its sample rays at its typical depth) in b's image across the
  // epipolar line, against where the live relative pose put it when the two
  // were matched.
  double PairShiftPx(const PosedKeyframe& a, const PosedKeyframe& b, const Rigid3d& final_a, const Rigid3d& final_b,
                     const FeatureMap& final_map) const;
  // Keyframes among the first `earlier_count` to match `added` with, most
  // overlapping first.
  std::vector<int> OverlappingKeyframes(const PosedKeyframe& added, int earlier_count) const;
  int Find(int node) const;
  bool Union(int a, int b);  // false (and no change) on a conflict
  std::vector<int> Members(int root) const;

  CameraModel camera_;
  FeatureMapOptions options_;
  std::vector<Eigen::Vector3d> view_sample_rays_;  // unit rays over the image, camera frame
  std::vector<PosedKeyframe> keyframes_;
  std::vector<int> first_node_;         // node of feature 0 of each keyframe
  // Union-find over every feature of every keyframe (node = first_node_ +
  // index), with each root's members for the conflict check.
  mutable std::vector<int> parent_;
  std::vector<int> node_keyframe_;
  std::vector<std::vector<int>> members_;  // at roots of 2+ nodes only
  // Each keyframe's matches with the earlier keyframes it was matched with.
  std::vector<std::vector<std::pair<int, std::vector<FeatureMatch>>>> pair_matches_;
};

}  // namespace tagsfm
