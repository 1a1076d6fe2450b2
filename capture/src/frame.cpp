#include "tagsfm/capture/frame.h"

#include <opencv2/imgproc.hpp>

namespace tagsfm {

cv::Mat ToGray8(const cv::Mat& image) {
  if (image.empty()) return {};
  cv::Mat gray;
  if (image.channels() == 3) {
    cv::cvtColor(image, gray, cv::COLOR_BGR2GRAY);
  } else if (image.channels() == 4) {
    cv::cvtColor(image, gray, cv::COLOR_BGRA2GRAY);
  } else {
    gray = image;
  }
  if (gray.depth() == CV_8U) return gray;
  cv::Mat gray8;
  const double scale = gray.depth() == CV_16U ? 1.0 / 257.0 : (gray.depth() == CV_32F || gray.depth() == CV_64F ? 255.0 : 1.0);
  gray.convertTo(gray8, CV_8U, scale);
  return gray8;
}

}  // namespace tagsfm
