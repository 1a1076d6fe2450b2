#pragma once
// Tag detection for video: detect only where the tags are expected.
//
// Each known tag's corners are predicted from the previous frames (constant
// velocity per corner) or taken from the caller (recon passes the map's
// reprojection from its pose estimate); libapriltag then runs only in padded
// regions around the predictions, and the detections are shifted back into
// the frame. A full-frame detection runs every `full_frame_every` frames, so
// that new tags appear, and at once on a frame where a predicted tag is not
// found in its region, so that a tag is never lost to a bad prediction.
#include <map>
#include <memory>
#include <optional>

#include <opencv2/core.hpp>

#include "tagsfm/core/result.h"
#include "tagsfm/detect/corner_refinement.h"
#include "tagsfm/detect/tag_detector.h"

namespace tagsfm {

struct TagTrackerOptions {
  int full_frame_every = 15;          // frames between full-frame detections (>= 1)
  double padding_px = 10.0;           // region margin around a predicted tag...
  double padding_fraction = 0.25;     // ...or this fraction of its size, if larger
  // Regions are searched at this decimation (1: full resolution, which also
  // finds small tags the full-frame pass at quad_decimate 2 misses).
  float region_quad_decimate = 1.0f;
  Status Check() const;
};

struct TagTrackerStats {
  int frames = 0;
  int full_frame_detections = 0;   // scheduled, first frame, or after a loss
  int recoveries = 0;              // full-frame detections caused by a lost tag
  int region_detections = 0;       // libapriltag runs on regions
};

class TagTracker {
 public:
  // `detector` is used for the full-frame passes (its decimation, threads);
  // regions use the same options with region_quad_decimate and one thread.
  static Result<std::unique_ptr<TagTracker>> Create(const TagDetectorOptions& detector,
                                                    const TagTrackerOptions& tracker);

  // Detects the tags of the next frame. `predicted`: corners where the caller
  // expects tags (they override the tracker's own prediction for those ids).
  Result<DetectionSet> Track(const cv::Mat& gray8, FrameId frame,
                             const std::map<TagId, QuadCorners>& predicted = {});

  // Forgets every tag: the next frame is detected in full.
  void Reset();

  const TagTrackerStats& stats() const { return stats_; }
  const TagTrackerOptions& options() const { return options_; }

 private:
  struct TagTrack {
    QuadCorners corners;
    FrameId frame = 0;
    std::optional<QuadCorners> previous;  // the sighting before, for the velocity
    FrameId previous_frame = 0;
  };

  TagTracker(TagTrackerOptions options, std::unique_ptr<TagDetector> full, std::unique_ptr<TagDetector> region);
  std::map<TagId, QuadCorners> Predict(FrameId frame, const std::map<TagId, QuadCorners>& predicted) const;
  Result<DetectionSet> DetectFullFrame(const cv::Mat& gray8, FrameId frame);
  void Update(const DetectionSet& detections);

  TagTrackerOptions options_;
  std::unique_ptr<TagDetector> full_detector_;
  std::unique_ptr<TagDetector> region_detector_;
  std::map<TagId, TagTrack> tracks_;
  int frames_since_full_ = 0;
  bool have_full_ = false;
  TagTrackerStats stats_;
};

}  // namespace tagsfm
