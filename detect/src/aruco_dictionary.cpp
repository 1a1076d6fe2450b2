#include "aruco_dictionary.h"

namespace tagsfm::detail {

cv::Ptr<cv::aruco::Dictionary> ArucoDictionaryFor(const std::string& family) {
  if (family == "tag36h11") return cv::aruco::getPredefinedDictionary(cv::aruco::DICT_APRILTAG_36h11);
  if (family == "tag36h10") return cv::aruco::getPredefinedDictionary(cv::aruco::DICT_APRILTAG_36h10);
  if (family == "tag25h9") return cv::aruco::getPredefinedDictionary(cv::aruco::DICT_APRILTAG_25h9);
  if (family == "tag16h5") return cv::aruco::getPredefinedDictionary(cv::aruco::DICT_APRILTAG_16h5);
  return nullptr;
}

}  // namespace tagsfm::detail
