#include "tagsfm/core/camera_model.h"

#include <cmath>
#include <sstream>

#include <opencv2/calib3d.hpp>

namespace tagsfm {
namespace {

std::string FieldError(const std::string& field, const std::string& rule, double got) {
  std::ostringstream out;
  out << "camera." << field << " " << rule << " (got " << got << ")";
  return out.str();
}

// Coefficient i of OpenCV's order, zero when absent.
double Coef(const std::vector<double>& d, size_t i) { return i < d.size() ? d[i] : 0.0; }

}  // namespace

const char* CameraModel::KindName(Kind kind) { return kind == Kind::kFisheye ? "fisheye" : "pinhole"; }

Status CameraModel::Check() const {
  if (width <= 0) return MakeError(FieldError("width", "must be > 0", width));
  if (height <= 0) return MakeError(FieldError("height", "must be > 0", height));
  if (!(fx > 0) || !std::isfinite(fx)) return MakeError(FieldError("fx", "must be > 0", fx));
  if (!(fy > 0) || !std::isfinite(fy)) return MakeError(FieldError("fy", "must be > 0", fy));
  if (!std::isfinite(cx)) return MakeError(FieldError("cx", "must be finite", cx));
  if (!std::isfinite(cy)) return MakeError(FieldError("cy", "must be finite", cy));
  const size_t n = distortion.size();
  if (kind == Kind::kFisheye) {
    if (n != 0 && n != 4) return MakeError(FieldError("distortion", "of a fisheye camera takes 4 values k1 k2 k3 k4", n));
  } else if (n != 0 && n != 4 && n != 5 && n != 8 && n != 12 && n != 14) {
    return MakeError(FieldError("distortion", "takes 4, 5, 8, 12 or 14 values", n));
  }
  for (double v : distortion) {
    if (!std::isfinite(v)) return MakeError(FieldError("distortion", "values must be finite", v));
  }
  return Status::Ok();
}

bool CameraModel::HasDistortion() const {
  for (double v : distortion) {
    if (v != 0.0) return true;
  }
  return false;
}

cv::Matx33d CameraModel::K() const { return cv::Matx33d(fx, 0, cx, 0, fy, cy, 0, 0, 1); }

cv::Mat CameraModel::DistortionMat() const {
  cv::Mat d(1, static_cast<int>(distortion.size()), CV_64F);
  for (size_t i = 0; i < distortion.size(); ++i) d.at<double>(0, static_cast<int>(i)) = distortion[i];
  return d;
}

Eigen::Vector2d CameraModel::Project(const Eigen::Vector3d& point_in_cam) const {
  const double x = point_in_cam.x() / point_in_cam.z();
  const double y = point_in_cam.y() / point_in_cam.z();
  double xd = x, yd = y;
  if (kind == Kind::kFisheye) {
    const double r = std::sqrt(x * x + y * y);
    const double theta = std::atan(r);
    const double t2 = theta * theta;
    const double theta_d = theta * (1 + t2 * (Coef(distortion, 0) +
                                              t2 * (Coef(distortion, 1) + t2 * (Coef(distortion, 2) + t2 * Coef(distortion, 3)))));
    const double scale = r > 1e-12 ? theta_d / r : 1.0;
    xd = x * scale;
    yd = y * scale;
  } else if (distortion.size() == 14) {
    // The tilted-sensor model is rare; OpenCV's own projection handles it.
    std::vector<cv::Point3d> object{{point_in_cam.x(), point_in_cam.y(), point_in_cam.z()}};
    std::vector<cv::Point2d> image;
    cv::projectPoints(object, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), cv::Mat(K()), DistortionMat(), image);
    return {image[0].x, image[0].y};
  } else if (!distortion.empty()) {
    const auto& d = distortion;
    const double r2 = x * x + y * y, r4 = r2 * r2, r6 = r4 * r2;
    const double radial = (1 + Coef(d, 0) * r2 + Coef(d, 1) * r4 + Coef(d, 4) * r6) /
                          (1 + Coef(d, 5) * r2 + Coef(d, 6) * r4 + Coef(d, 7) * r6);
    const double p1 = Coef(d, 2), p2 = Coef(d, 3);
    xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x) + Coef(d, 8) * r2 + Coef(d, 9) * r4;
    yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y + Coef(d, 10) * r2 + Coef(d, 11) * r4;
  }
  return {fx * xd + cx, fy * yd + cy};
}

std::vector<Eigen::Vector2d> CameraModel::PixelsToNormalized(const std::vector<Eigen::Vector2d>& pixels) const {
  std::vector<Eigen::Vector2d> out(pixels.size());
  if (pixels.empty()) return out;
  if (!HasDistortion()) {
    for (size_t i = 0; i < pixels.size(); ++i) out[i] = {(pixels[i].x() - cx) / fx, (pixels[i].y() - cy) / fy};
    return out;
  }
  std::vector<cv::Point2d> src(pixels.size()), dst;
  for (size_t i = 0; i < pixels.size(); ++i) src[i] = {pixels[i].x(), pixels[i].y()};
  // More iterations than OpenCV's default 5: strong distortion needs them to
  // reach the 1e-3 px that corner accuracy is measured at.
  const cv::TermCriteria criteria(cv::TermCriteria::COUNT + cv::TermCriteria::EPS, 50, 1e-12);
  if (kind == Kind::kFisheye) {
    cv::fisheye::undistortPoints(src, dst, cv::Mat(K()), DistortionMat(), cv::noArray(), cv::noArray(), criteria);
  } else {
    cv::undistortPoints(src, dst, cv::Mat(K()), DistortionMat(), cv::noArray(), cv::noArray(), criteria);
  }
  for (size_t i = 0; i < pixels.size(); ++i) out[i] = {dst[i].x, dst[i].y};
  return out;
}

Eigen::Vector2d CameraModel::PixelToNormalized(const Eigen::Vector2d& pixel) const {
  return PixelsToNormalized({pixel})[0];
}

}  // namespace tagsfm
