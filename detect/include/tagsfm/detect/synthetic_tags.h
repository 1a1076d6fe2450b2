#pragma once
// Images of tags whose corners are known exactly, for accuracy tests and
// benchmarks: each tag's bitmap (libapriltag's own, one white module around
// the black border, plus any further white margin) is mapped by a
// homography over a flat or textured background, blurred, area-averaged
// over each pixel and noised. Pixel centres at integer coordinates
// (pixel (x, y) covers [x-0.5, x+0.5] x [y-0.5, y+0.5]), as everywhere in tagsfm.
#include <cstdint>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "tagsfm/core/camera_model.h"
#include "tagsfm/core/result.h"
#include "tagsfm/detect/corner_refinement.h"
#include "tagsfm/detect/tag_detection.h"

namespace tagsfm {

// Where a tag lands: its corner square's corners, libapriltag's order.
struct PlacedTag {
  TagId id = 0;
  QuadCorners corners;
};

struct TagRenderOptions {
  int supersample = 8;         // coarse grid per pixel axis; pixels an edge crosses get 987 samples
  double blur_sigma_px = 0.0;  // Gaussian optical blur, applied before the pixels integrate
  // With blur: the scene is drawn this many times finer, blurred there and
  // block-averaged, so that the blur acts before the pixel's area as in a
  // camera (as `tagsfm synth` does). 1: blur the area-averaged pixels
  // (cheaper, not physical below ~1 px of blur).
  int blur_oversample = 4;
  double noise_sigma = 0.0;    // Gaussian noise, grey levels
  double black = 30.0;         // grey levels of the tag's black and white
  double white = 220.0;
  double background = 140.0;   // outside the tags' paper (the texture's mean)
  // White modules round the black square, the background beyond: 1 =
  // libapriltag's bitmap printed edge to edge (its own outer ring), 2 = one
  // module of paper more (what this raster drew before it had the option).
  double margin_modules = 1.0;
  // Background texture (value noise, blobs and strokes of random grey, sharp
  // to a pixel) of about this many grey levels either side of `background`,
  // clipped to [black, white - 20]; 0: a flat background.
  double texture_contrast = 0.0;
  // Each tag's black and white scaled by its own shade, uniform in
  // [1 - tag_shade_variation, 1] (lighting that differs per surface).
  double tag_shade_variation = 0.0;
  std::uint64_t seed = 1;
  // Optional lens (not owned): with distortion (pinhole k1, k2, p1, p2, k3),
  // the tags' corners are undistorted pixel coordinates (this camera's K
  // without distortion) and the image is what the distorting lens sees, so a
  // corner's true image position is camera->Project of its ray.
  const CameraModel* camera = nullptr;
};

// An 8-bit grey image with the tags drawn; ids beyond the family, an unknown
// family or a bad size are errors.
Result<cv::Mat> RenderTags(const std::string& family, int width, int height, const std::vector<PlacedTag>& tags,
                           const TagRenderOptions& options);

// Tag `id` seen by a camera of focal 1000 px from 1 m away: a square of
// `side_px` / 1000 m turned by `rotation` (tag frame: x right, y down in the
// image before turning, z away), its centre on the ray through (cx, cy);
// corners in libapriltag's order.
PlacedTag TagSeenFromOneMetre(int id, double cx, double cy, double side_px, const Eigen::Matrix3d& rotation);

// `count` tags of the family (ids 0..count-1) seen in perspective: each a
// square of about `side_px` pixels, tilted up to `max_tilt_deg` about a random
// axis in the tag plane and rotated at random in the image, laid on a grid so
// that they never overlap. Fewer come back when the image is too small.
std::vector<PlacedTag> RandomTagPlacements(int width, int height, int count, double side_px, double max_tilt_deg,
                                           std::uint64_t seed);

// A video-like sequence: the tags of RandomTagPlacements seen by a camera
// that pans (`pan_px_per_frame` along x, half that along y), rolls 0.1 degree
// per frame and shakes by about a pixel; tags leaving the image (with a
// 2 px margin) are left out of that frame.
std::vector<std::vector<PlacedTag>> VideoTagPlacements(int width, int height, int count, double side_px, int frames,
                                                       double pan_px_per_frame, std::uint64_t seed);

}  // namespace tagsfm
