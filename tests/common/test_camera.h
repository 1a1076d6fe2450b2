#pragma once
// A distortion-free pinhole camera for tests that need only its geometry.
#include "tagsfm/core/camera_model.h"

namespace tagsfm::testing {

inline CameraModel PinholeCamera(int width, int height, double focal_px, double cx, double cy) {
  CameraModel c;
  c.width = width;
  c.height = height;
  c.fx = c.fy = focal_px;
  c.cx = cx;
  c.cy = cy;
  return c;
}

}  // namespace tagsfm::testing
