#pragma once
// The natural-feature half of the hybrid pipeline (docs/features.md): on
// each registered keyframe of the reconstruction (one keyframe rule) SIFT
// features are extracted and matched, guided by the frame's target-derived
// pose, with the earlier keyframes that see the same part of the scene
// (feature/feature_map.h); at the end the tracks are triangulated from the
// final poses and adjusted with the targets (Reconstructor::Finish).
//
// Live (`run`, `replay --realtime`) the work runs on a worker thread fed by
// a bounded queue, so that capture and tag tracking never wait; keyframes
// whose work was dropped there are redone at Finish from the recording, in
// keyframe order, so the points equal a plain replay's.
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "tagsfm/capture/frame.h"
#include "tagsfm/feature/feature_extractor.h"
#include "tagsfm/feature/feature_map.h"
#include "tagsfm/recon/reconstructor.h"

namespace tagsfm {

struct FeatureStageOptions {
  bool enabled = true;  // false: targets only (photogrammetry alone)
  // Extract and match on a worker thread (set by `run` and `replay
  // --realtime`); a plain replay works in line, deterministically.
  bool background = false;
  // Keyframes waiting for the worker; beyond, the oldest waiting one is
  // dropped live (and redone at Finish).
  int max_queued_keyframes = 2;
  FeatureExtractorOptions extractor;
  FeatureMapOptions map;
  // Larger images are scaled down to this longer side for SIFT (its cost
  // grows with the pixel count). 0: never.
  int max_feature_image_side = 1280;
  // A keyframe's scene lies between the median depth of the mapped target
  // corners in view divided and multiplied by this (the guided matcher's
  // search band; docs/features.md, "Pipeline").
  double depth_range_factor = 2.0;
  // Depths assumed when no mapped target is in view, metres.
  double fallback_near_m = 0.2;
  double fallback_far_m = 20.0;
  // Live cloud: points triangulated with the keyframes' poses at most this
  // often, and at most a quarter of the worker's time.
  double live_cloud_interval_s = 1.0;
  int live_cloud_max_points = 2000;
  // Threads of the final triangulation and refinement (at Finish, when
  // capture is over; the points are the same for any number).
  int finish_threads = 2;
  // Threads matching a keyframe with its earlier neighbours, a pair each,
  // in a plain replay and at Finish; live, the worker matches on one, leaving
  // the other core to capture and the tags. The tracks are the same for any
  // number.
  int match_threads = 2;
  // At Finish, match the keyframes again from the final poses and camera
  // before triangulating (FeatureMap::Rematch): live poses, and a lens not
  // yet refined, push true matches out of the epipolar band.
  bool rematch_final_poses = true;

  Status Check() const;  // names the wrong field ("features.map.min_overlap ...")
};

// What the live cloud shows (LiveStatus' feature block).
struct LiveCloud {
  int points = 0;                              // triangulated so far
  std::vector<Eigen::Vector3f> sample;         // at most live_cloud_max_points, world frame, metres
  int keyframes = 0;                           // keyframes in the feature map so far
  int dropped = 0;                             // keyframes whose work was dropped live
};

using FeatureFrameLoader = std::function<Result<Frame>(FrameId)>;

class FeatureStage {
 public:
  // `live_cloud`: keep a coarse cloud up to date while running (LiveCloud).
  static Result<std::unique_ptr<FeatureStage>> Create(const CameraModel& camera, const FeatureStageOptions& options,
                                                      bool live_cloud);
  ~FeatureStage();
  FeatureStage(const FeatureStage&) = delete;
  FeatureStage& operator=(const FeatureStage&) = delete;

  // Whether a frame is a feature keyframe: a registered keyframe of the reconstruction.
  bool SelectKeyframe(const FrameReport& report) const;
  // A selected keyframe, seen from report.cam_from_world, with the targets
  // mapped so far (its depth range). `frame` null: its image is not at hand
  // (frames reconstructed after calibration); Complete reads it again.
  void AddKeyframe(const Frame* frame, const DetectionSet& tags, const FrameReport& report,
                   const TargetCornerMap& mapped_corners);
  // Waits for the worker, then brings in the keyframes not in the map yet
  // (dropped live, or without an image), read again with `reload`, in
  // keyframe order. Call once, before Triangulate.
  void Complete(const FeatureFrameLoader& reload);
  // Points of every track from the final poses (matched again from them
  // first, with rematch_final_poses); `stats`, when given, says where the
  // tracks went.
  std::vector<FeaturePoint> Triangulate(const PoseMap& cam_from_world, const CameraModel& camera,
                                        FeatureTriangulationStats* stats = nullptr);

  LiveCloud live_cloud() const;              // any thread
  std::vector<std::string> TakeWarnings();   // one line each
  std::vector<double> keyframe_ms() const;   // extraction and matching per keyframe
  int dropped() const;
  int rematched() const;  // keyframes Triangulate matched again (FeatureMap::Rematch)

 private:
  struct State;
  explicit FeatureStage(std::unique_ptr<State> state);
  std::unique_ptr<State> state_;
};

// The depth range of a keyframe's scene: the median depth of the mapped
// target corners in front of the camera and inside the image, divided and
// multiplied by `factor`; nullopt when none is.
std::optional<DepthRange> TargetDepthRange(const TargetCornerMap& corners, const Rigid3d& cam_from_world,
                                           const CameraModel& camera, double factor);

}  // namespace tagsfm
