#pragma once
// AprilTag targets with sub-pixel corners, on libapriltag.
// (Interface fixed by the foundation so recon can build against it; the
// detection work fills in the implementation and may add options.)
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "tagsfm/core/camera_model.h"
#include "tagsfm/core/result.h"
#include "tagsfm/detect/tag_detection.h"

namespace tagsfm {

enum class CornerRefinement {
  kNone,         // libapriltag's corners as they come (shifted to OpenCV's convention)
  kAprilTag,     // libapriltag's own edge refinement
  kCornerSubPix, // OpenCV cornerSubPix
  kEdgeLineFit,  // fit the tag's four outer edges, intersect the lines
};

// "none", "apriltag", "cornersubpix", "edgelinefit" (the CLI and config names).
const char* CornerRefinementName(CornerRefinement refinement);
Result<CornerRefinement> ParseCornerRefinement(const std::string& name);

struct TagDetectorOptions {
  std::string family = "tag36h11";
  float quad_decimate = 2.0f;
  float quad_sigma = 0.0f;    // Gaussian blur (>0) or sharpening (<0) of the segmentation image
  int threads = 2;
  bool refine_edges = true;   // libapriltag's refine_edges
  double decode_sharpening = 0.25;
  CornerRefinement refinement = CornerRefinement::kEdgeLineFit;
  double min_decision_margin = 30.0;  // reject weaker decodes
  int max_hamming = 0;                // reject decodes with more bit errors (0..2; also
                                      // the bits libapriltag tries to correct)
  // A second pass for tags libapriltag's segmentation misses (about 2 px
  // modules, or blurred by about a module; see docs/detection.md): OpenCV
  // aruco's quad candidates, read by tagsfm. First one sample per module
  // centre: refined like any tag and read again, only an exact code with
  // every border module dark, every module of the white ring around it light
  // and every bit at least small_tag_min_margin (of the local black-white
  // contrast) from the threshold counts. Where that fails, a model of the
  // whole blurred tag fitted to the pixels (corners, blur, levels, bits):
  // only an exact code that the model explains counts. Only ids the first
  // pass did not find; off by default (costs ~10-20 ms CPU per frame at
  // 816x612-1280x720, plus ~20 ms per blurred tag read by the model). With
  // refinement none or apriltag the added tags keep the reading's corners.
  // Needs a family OpenCV aruco knows and whose code is strong enough to
  // read arbitrary quads: tag36h11, tag36h10, tag25h9 (Create fails else).
  bool small_tag_pass = false;
  double small_tag_min_margin = 0.02;
  // The lens, when known: with distortion the edge-line fit works in
  // undistorted pixels, where the tag's edges are straight (see
  // RefineCornersByEdgeLines). Without: the edges are taken as straight in
  // the image.
  std::optional<CameraModel> camera;
  // Drop tags cut by the image border (ClearOfImageBorder). Off for a
  // detector run on parts of an image (the tracker's regions), whose edges
  // are not the image's: the tracker's full detector drops them after.
  bool drop_tags_cut_by_border = true;

  Status Check() const;  // names the wrong field
};

// Whether the small-tag pass can read tags of `family` (an error naming why
// not: no aruco dictionary, or a code too weak to read arbitrary quads).
Status SmallTagPassCanRead(const std::string& family);

class TagDetector {
 public:
  static Result<std::unique_ptr<TagDetector>> Create(const TagDetectorOptions& options);
  virtual ~TagDetector() = default;

  // Detects every tag in an 8-bit grey image. An empty or tiny image gives an
  // empty set; a wrong image type is an error. The image may be a view into a
  // larger one (any row stride): it is read in place, not copied. Tags come
  // sorted by id. Not safe to call from two threads at once.
  virtual Result<DetectionSet> Detect(const cv::Mat& gray8, FrameId frame) = 0;

  // Refines the corners of `tags` (found in `gray8`, e.g. by a detector with
  // refinement kNone on parts of it) with this detector's refinement, on its
  // threads. A tag whose refinement fails keeps its corners. A tag cut by
  // the image border (ClearOfImageBorder) is dropped, as Detect drops it.
  virtual void RefineDetections(const cv::Mat& gray8, std::vector<TagDetection>* tags) = 0;

  // Modules across the tag's outer (corner-defining) square, e.g. 8 for
  // tag36h11: corner spacing / this = module size in pixels.
  virtual int ModulesAcrossCornerSquare() const = 0;
  const TagDetectorOptions& options() const { return options_; }

 protected:
  explicit TagDetector(TagDetectorOptions options) : options_(std::move(options)) {}
  TagDetectorOptions options_;
};

}  // namespace tagsfm
