#pragma once
// OpenCV aruco's dictionary of an AprilTag family, where aruco has one:
// the tracker's entry-band candidates and the detector's small-tag pass
// both start from aruco's quads.
#include <string>

#include <opencv2/aruco.hpp>

namespace tagsfm::detail {

// Null for the families aruco lacks (all but tag36h11, tag36h10, tag25h9, tag16h5).
cv::Ptr<cv::aruco::Dictionary> ArucoDictionaryFor(const std::string& family);

}  // namespace tagsfm::detail
