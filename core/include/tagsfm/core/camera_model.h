#pragma once
// The camera of a recording: OpenCV's pinhole model with radial-tangential
// distortion (4, 5, 8, 12 or 14 coefficients), or OpenCV's fisheye
// (equidistant) model with k1..k4. Pixel centres are at integer coordinates
// (OpenCV's convention), everywhere in tagsfm.
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "tagsfm/core/result.h"

namespace tagsfm {

struct CameraModel {
  enum class Kind { kPinhole, kFisheye };

  Kind kind = Kind::kPinhole;
  int width = 0;
  int height = 0;
  double fx = 0, fy = 0, cx = 0, cy = 0;
  std::vector<double> distortion;  // OpenCV's order; empty means none

  // Names the first wrong field, e.g. "camera.fx must be > 0 (got -3)".
  Status Check() const;

  bool HasDistortion() const;
  cv::Matx33d K() const;
  cv::Mat DistortionMat() const;  // 1xN CV_64F, as OpenCV's functions take it

  // Projects a point in the camera frame (z > 0) to pixels, with distortion.
  Eigen::Vector2d Project(const Eigen::Vector3d& point_in_cam) const;
  // Inverse of Project for one pixel: the normalised image point (x/z, y/z).
  Eigen::Vector2d PixelToNormalized(const Eigen::Vector2d& pixel) const;
  // Batch undistortion to normalised coordinates (faster than one by one).
  std::vector<Eigen::Vector2d> PixelsToNormalized(const std::vector<Eigen::Vector2d>& pixels) const;

  static const char* KindName(Kind kind);
};

}  // namespace tagsfm
