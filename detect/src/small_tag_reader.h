#pragma once
// Reading a quadrilateral as an AprilTag with tagsfm's own decoder, for the
// small-tag pass of TagDetector (options.small_tag_pass).
//
// libapriltag misses tags of ~2 px modules because its segmentation (a
// threshold over 4x4 px tiles) breaks their one-module black border or
// joins it to dark surroundings, so no quad is fitted; OpenCV aruco's
// adaptive-threshold contours still outline them (and its own reading of
// the bits fails at that size). So: aruco's candidates, read here.
#include <optional>

#include <apriltag/apriltag.h>
#include <opencv2/core.hpp>

#include "tagsfm/detect/corner_refinement.h"
#include "tagsfm/detect/tag_detection.h"

namespace tagsfm::detail {

struct QuadReading {
  TagId id = -1;
  int hamming = 0;
  double margin = 0.0;    // worst module's distance from the threshold, over the contrast
  double contrast = 0.0;  // mean white - black, grey levels
  QuadCorners corners;    // libapriltag's corner order
};

// Reads the quad `q` (any start, either winding) as a tag of `family`:
// homography from libapriltag's tag frame, the family's bits sampled at
// the module centres, black and white levels as planes fitted to the
// border ring and to the white ring outside it. Best reading of the eight
// corner orders with at most `max_hamming` bit errors, the border/white
// ring counted in the margin; nullopt if none.
std::optional<QuadReading> ReadQuad(const cv::Mat& g, const apriltag_family_t* family, const QuadCorners& q,
                                    int max_hamming, double min_contrast);

// Bilinear sample of an 8-bit image, pixel centres at integers; nullopt
// outside the image.
std::optional<double> SampleBilinear(const cv::Mat& g, double x, double y);

// Whether `p` lies inside (or on) the quadrilateral.
bool InsideQuad(const QuadCorners& quad, const Eigen::Vector2d& p);

}  // namespace tagsfm::detail
