#pragma once
// Where features may be detected: everything but the tags.
#include <opencv2/core.hpp>

#include "tagsfm/detect/tag_detection.h"

namespace tagsfm {

// 255 outside the tags (each grown by `margin` of its size), 0 on them: a
// tag's corners are targets already, and its code would match other tags'.
cv::Mat MaskOutsideTags(const cv::Size& size, const DetectionSet& tags, double margin);

}  // namespace tagsfm
