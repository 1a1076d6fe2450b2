#pragma once
// Reading a quadrilateral as an AprilTag whose modules are blurred into one
// another, for the small-tag pass of TagDetector.
//
// ReadQuad (small_tag_reader.h) thresholds one sample per module: at ~2 px
// modules, or under a few pixels of motion blur, a module's centre already
// carries much of its neighbours' shade and single modules read on the wrong
// side. Here the whole tag is modelled instead: the image over the tag and
// the white ring around it is the tag's reflectance (border black, ring and
// beyond white, the bits unknown in [0, 1]) convolved with a Gaussian blur
// along each tag axis, under black and white levels that are planes. Given
// the blur and the levels the bits are a linear least-squares problem; the
// levels are re-fitted given the bits, and the blur is searched. The bits are
// then read from the estimate: deconvolution, what libapriltag's
// decode_sharpening approximates with a fixed Laplacian.
#include <optional>

#include <apriltag/apriltag.h>
#include <opencv2/core.hpp>

#include "small_tag_reader.h"

namespace tagsfm::detail {

struct BlurredQuadReading {
  QuadReading reading;   // margin: the least |bit - 0.5| of the estimated bits (reflectance units)
  double residual = 0.0; // RMS of the model with the code's bits, over the contrast
  double blur_u = 0.0;   // the blur found along the tag's two axes: Gaussian sigma, modules
  double blur_v = 0.0;
  double blur_correlation = 0.0;  // of the two axes' blur: a motion along neither
};

// Whether the family has the layout modelled here: a black border ring of
// width_at_border modules, a white ring outside it, all bits inside.
bool BlurredReadingSupports(const apriltag_family_t* family);

// Reads the quad `q` (any start, either winding) as a tag of `family`; the
// best of the eight corner orders with at most `max_hamming` bit errors, or
// nullopt (unsupported family, quad partly outside the image, contrast below
// `min_contrast` grey levels, no code within max_hamming).
std::optional<BlurredQuadReading> ReadBlurredQuad(const cv::Mat& g, const apriltag_family_t* family,
                                                  const QuadCorners& q, int max_hamming, double min_contrast);

}  // namespace tagsfm::detail
