#pragma once
// Lossless PNG for recorded frames, written for speed at both ends: every
// row with PNG's Up filter (the row above subtracted) and zlib's run-length
// strategy at level 1. Against OpenCV 4.6's PNG writer (level 1, libpng's
// adaptive filters, mostly Paeth) this was measured 2-13 % smaller, 2.0-3.2x
// as fast to write and 2.0-2.2x as fast to read, on rendered and real frames
// (docs/capture.md); OpenCV 4.6 cannot choose the filter itself.
#include <vector>

#include <opencv2/core/mat.hpp>

#include "tagsfm/core/result.h"

namespace tagsfm {

// 8- or 16-bit, grey (1 channel), BGR (3) or BGRA (4); any other type is an
// error. Any PNG reader gives the same pixels back.
Result<std::vector<unsigned char>> EncodePng(const cv::Mat& image);

}  // namespace tagsfm
