#pragma once
// Tag detection for video: detect only where the tags are expected.
//
// Each known tag's corners are predicted from the previous frames (constant
// velocity per corner) or taken from the caller (recon passes the map's
// reprojection from its pose estimate); libapriltag then runs only in padded
// regions around the predictions, and the detections are shifted back into
// the frame. New tags: on every frame, bands along the image borders across
// which the image content flows in (the flow fitted to the tracked tags'
// last motion) are searched (by aruco candidates confirmed by libapriltag,
// or by libapriltag at the full-frame decimation), so that a tag entering
// the view is found on the first frame it is wholly inside, as a full-frame
// detection would find it; only tags not tracked already are kept from the
// bands. Few, small tags: where fewer than fine_search_below_tags tags are
// in view and some have modules under region_coarse_module_px, full-frame
// passes and entry bands run at region_quad_decimate, which finds the small
// and blurred tags the coarse decimation misses. A full-frame detection runs every `full_frame_every` frames
// (tags appearing inside the view, e.g. from behind an occluder), and at once
// on a frame where a predicted tag that should be wholly in view is not found
// in its region, so that a tag is never lost to a bad prediction. When the
// predictions keep failing (a photo set, a camera jerked about: the tags move
// too far between frames), tracking backs off: after n recoveries in a row
// the next 2^n - 1 frames (at most full_frame_every - 1) are detected in full
// before tracking is tried again, so that such input costs little more than a
// full-frame detection on each frame. Regions and
// bands are searched in parallel on the detector's threads and all tags are
// refined in parallel.
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <vector>

#include <opencv2/core.hpp>

#include "tagsfm/core/result.h"
#include "tagsfm/detect/corner_refinement.h"
#include "tagsfm/detect/tag_detector.h"

namespace tagsfm {
namespace detail {
class BandCandidates;
class DetectionWorkers;
}

struct TagTrackerOptions {
  int full_frame_every = 15;          // frames between full-frame detections (>= 1)
  // ...or sooner, once the tracked tags have moved this fraction of the
  // image's larger side since the last one: a tag that comes into sight
  // inside the view (from behind an occluder, or decodable again after a
  // few frames too oblique or blurred) is found before a fast pan carries it
  // out. Turning 100 degrees a second round a room, such a tag was read in
  // one frame of the 15 it was in view. A slow camera keeps the schedule.
  double full_frame_after_motion = 0.25;
  double padding_px = 10.0;           // region margin around a predicted tag...
  double padding_fraction = 0.25;     // ...or this fraction of its size, if larger
  // Regions are searched at this decimation (1: full resolution, which also
  // finds small tags the full-frame pass at quad_decimate 2 misses).
  float region_quad_decimate = 1.0f;
  // ...except regions whose tags have modules of at least this many pixels
  // (mean side over the modules across), searched at the detector's own
  // decimation, on a quarter of the pixels: libapriltag at quad_decimate 2
  // misses no such tag tilted up to 50 degrees (1280x720, 24-36 px tags:
  // misses only below 3.3 px), but some up to 4.4 px at 70 degrees, so a
  // tag not found there is looked for again at region_quad_decimate before
  // it counts as lost. (3.5 px measured no faster in detect_bench.)
  double region_coarse_module_px = 4.0;
  // Entry bands for new tags (see above). A band's width is
  // entry_band_tag_sizes times the largest tracked tag's extent plus the
  // inflow per frame and entry_band_margin_px. A tag that has just come
  // wholly into view, its white quiet zone (an eighth of its extent on each
  // side) included, reaches at most 1.25 extents plus the inflow into the
  // image: it lies in the band, unless it is larger than every tag in view.
  // (Bands are a third of the tracking's search time: 1.5 extents plus 10 px
  // cost ~25 % more at 720p for no recall.)
  bool search_entry_bands = true;
  double entry_band_tag_sizes = 1.25;
  double entry_band_margin_px = 3.0;
  // The band holds this many frames of inflow: with 2, a tag up to one
  // frame's inflow larger than the tracked ones still lies wholly in it on
  // the frame it comes in. In a fast pan round a room (80 px a frame) a tag
  // nearer than the others, twice their size, came in beside 1-frame bands
  // and was missed for 7 frames, which broke the map's chain. A slow camera
  // keeps its bands (and their cost): the inflow term is small there.
  double entry_band_inflow_frames = 2.0;
  // Bands searched by candidates: OpenCV's aruco (families it has a
  // dictionary for: tag36h11, tag36h10, tag25h9, tag16h5) says where tags
  // are, libapriltag confirms each one not tracked already in a small
  // region. ~5x cheaper than libapriltag on the whole band. Only while the
  // smallest tag in view has modules (mean side over modules across) of
  // entry_band_candidates_min_module_px or more: aruco finds more small
  // tags than libapriltag at quad_decimate 2, but not all the same ones;
  // over 720 tags of 24-36 px tilted up to 70 degrees it missed 9 that
  // libapriltag found, all with modules of 3.23 px or less.
  // Off, smaller tags or another family: libapriltag on the whole band.
  bool entry_band_candidates = true;
  double entry_band_candidates_min_module_px = 3.5;
  // A border gets a band where the content flows in by at least this much
  // per frame somewhere along it; slower borders (and a still camera) are
  // left to the full-frame passes, which a tag takes many frames to escape.
  // While no tag has been seen twice (the motion unknown), every border is searched.
  double entry_min_inflow_px = 0.5;
  // Full-frame passes and entry bands at region_quad_decimate while fewer
  // tags than this are found at the detector's decimation and some of them
  // have modules under region_coarse_module_px: a frame with few tags needs
  // the small ones to be posed at all (a blurred 640x360 walk behind a lens
  // registered 3 of 20 frames without), but where enough are found the
  // small ones' less precise corners cost more than they add (on a
  // 1280x720 walk, 28 tags instead of 23 moved its scale from -205 to
  // -434 ppm), and the fine pass costs ~4x the coarse one. 0: never.
  int fine_search_below_tags = 4;
  // Back off after recoveries (see above). Off: every frame tries tracking.
  bool back_off_after_recovery = true;
  Status Check() const;
};

struct TagTrackerStats {
  int frames = 0;
  int full_frame_detections = 0;   // scheduled, first frame, or after a loss
  int fine_full_frame_detections = 0;  // of those, at region_quad_decimate: the tags in view are small
  int recoveries = 0;              // full-frame detections caused by a lost tag
  int backed_off = 0;              // full-frame detections while backing off after recoveries
  int region_detections = 0;       // libapriltag runs on regions
  int band_detections = 0;         // libapriltag runs on entry bands
  int tags_found_in_bands = 0;     // new tags the entry bands found
  // Where the time goes (ms, summed over frames): CPU time of the searches
  // on their threads (robust to other load), wall time of the rest.
  double region_cpu_ms = 0.0;      // libapriltag on regions
  double band_cpu_ms = 0.0;        // libapriltag on entry bands
  double refine_ms = 0.0;          // edge fit of the tags found in regions and bands (wall)
  double full_frame_ms = 0.0;      // full-frame detections, refinement included (wall)
};

class TagTracker {
 public:
  // `detector` is used for the full-frame passes (its decimation, threads)
  // and the refinement; regions use the same options with
  // region_quad_decimate, entry bands the detector's decimation, each run on
  // one of the detector's threads.
  ~TagTracker();
  static Result<std::unique_ptr<TagTracker>> Create(const TagDetectorOptions& detector,
                                                    const TagTrackerOptions& tracker);

  // Detects the tags of the next frame. `predicted`: corners where the caller
  // expects tags (recon: the map projected with the extrapolated pose). They
  // override the tracker's own prediction for those ids; a predicted tag the
  // last frame did not have is searched, but not finding it is no loss (no
  // full-frame pass follows): it may be hidden, or too oblique to decode.
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

  // Per thread: libapriltag detectors are not reentrant.
  struct ThreadDetectors {
    std::unique_ptr<TagDetector> region;  // at region_quad_decimate
    std::unique_ptr<TagDetector> band;    // at the detector's decimation: bands, coarse regions
  };
  struct Search {
    cv::Rect area;
    bool band = false;
    bool coarse = false;              // at the detector's decimation (bands unless the tags are small)
    bool by_candidates = false;       // a band searched by candidates (BandCandidates)
    std::vector<TagDetection> found;  // frame coordinates, unrefined
  };

  TagTracker(TagTrackerOptions options, std::unique_ptr<TagDetector> full, std::unique_ptr<TagDetector> fine_full,
             std::vector<ThreadDetectors> per_thread, std::unique_ptr<detail::BandCandidates> candidates);
  Status SearchArea(const cv::Mat& gray8, FrameId frame, int thread, Search* search) const;
  Status SearchFine(const cv::Mat& gray8, FrameId frame, TagId id, const QuadCorners& corners,
                    std::vector<TagDetection>* found);
  Status SearchBandCandidates(const cv::Mat& gray8, FrameId frame, const std::vector<cv::Rect>& regions, int thread,
                              Search* band) const;
  std::map<TagId, QuadCorners> Predict(FrameId frame, const std::map<TagId, QuadCorners>& predicted) const;
  void AddEntryBands(const cv::Size& image, std::vector<Search>* searches) const;
  Result<DetectionSet> DetectFullFrame(const cv::Mat& gray8, FrameId frame,
                                       const std::map<TagId, QuadCorners>& expected);
  Result<DetectionSet> DetectWholeImage(const cv::Mat& gray8, FrameId frame);
  bool FewAndSmall(size_t tags, double smallest_module_px) const;
  bool FewSmallTags(const std::vector<TagDetection>& found) const;
  bool FewSmallTracked() const;
  void Update(const DetectionSet& detections);
  // Track's steps on a tracked frame.
  void PlanSearches(const cv::Size& image, const std::map<TagId, QuadCorners>& expected);
  Status RunSearches(const cv::Mat& gray8, FrameId frame);
  DetectionSet TakeFound(FrameId frame, std::set<TagId>* found_ids);
  Status SearchMissed(const cv::Mat& gray8, FrameId frame, const std::map<TagId, QuadCorners>& expected,
                      const std::set<TagId>& found_ids, std::vector<TagDetection>* found, bool* lost);

  TagTrackerOptions options_;
  std::unique_ptr<TagDetector> full_detector_;
  // The full frame at region_quad_decimate, for scenes whose tags are too
  // small for the detector's decimation; null when that is no finer.
  std::unique_ptr<TagDetector> fine_full_detector_;
  std::vector<ThreadDetectors> per_thread_;
  std::unique_ptr<detail::BandCandidates> band_candidates_;  // null: bands by libapriltag
  std::unique_ptr<detail::DetectionWorkers> workers_;
  std::vector<Search> searches_;  // reused from frame to frame
  std::map<TagId, TagTrack> tracks_;
  int frames_since_full_ = 0;
  double motion_since_full_px_ = 0.0;  // the tracked tags' median motion, summed since the last full-frame pass
  bool have_full_ = false;
  int recoveries_in_a_row_ = 0;      // tracking attempts that ended in a recovery, since one did not
  int full_frames_before_retry_ = 0;  // backing off: full-frame detections left before tracking again
  TagTrackerStats stats_;
};

}  // namespace tagsfm
