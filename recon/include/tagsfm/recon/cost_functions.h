#pragma once
// The residuals of the adjustment, one small functor per kind. Observations
// are undistorted to normalised image coordinates once (CameraModel::
// PixelsToNormalized), and residuals are scaled back by fx, fy so they read
// in pixels. Poses are PoseParams arrays: quaternion (x, y, z, w) + translation.
#include <ceres/autodiff_cost_function.h>
#include <ceres/rotation.h>

#include <array>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace tagsfm {

namespace cost_detail {
template <class T>
Eigen::Matrix<T, 3, 1> Transform(const T* q, const T* t, const Eigen::Matrix<T, 3, 1>& point) {
  const Eigen::Map<const Eigen::Quaternion<T>> rotation(q);
  const Eigen::Map<const Eigen::Matrix<T, 3, 1>> translation(t);
  return rotation * point + translation;
}
template <class T>
void ProjectResidual(const Eigen::Matrix<T, 3, 1>& point_in_cam, const Eigen::Vector2d& observed, double fx, double fy,
                     T* residual) {
  residual[0] = T(fx) * (point_in_cam.x() / point_in_cam.z() - T(observed.x()));
  residual[1] = T(fy) * (point_in_cam.y() / point_in_cam.z() - T(observed.y()));
}
}  // namespace cost_detail

// A free 3D point seen by a camera: blocks cam_q[4], cam_t[3], point_in_world[3].
struct ReprojectionError {
  ReprojectionError(const Eigen::Vector2d& observed_normalized, double fx, double fy)
      : observed(observed_normalized), fx(fx), fy(fy) {}
  template <class T>
  bool operator()(const T* cam_q, const T* cam_t, const T* point, T* residual) const {
    const Eigen::Matrix<T, 3, 1> p(point[0], point[1], point[2]);
    cost_detail::ProjectResidual(cost_detail::Transform(cam_q, cam_t, p), observed, fx, fy, residual);
    return true;
  }
  static ceres::CostFunction* Create(const Eigen::Vector2d& observed_normalized, double fx, double fy) {
    return new ceres::AutoDiffCostFunction<ReprojectionError, 2, 4, 3, 3>(
        new ReprojectionError(observed_normalized, fx, fy));
  }
  Eigen::Vector2d observed;
  double fx, fy;
};

// A point held fixed (a known-map corner) seen by a camera: blocks cam_q, cam_t.
struct FixedPointReprojectionError {
  FixedPointReprojectionError(const Eigen::Vector2d& observed_normalized, const Eigen::Vector3d& point_in_world,
                              double fx, double fy)
      : observed(observed_normalized), point(point_in_world), fx(fx), fy(fy) {}
  template <class T>
  bool operator()(const T* cam_q, const T* cam_t, T* residual) const {
    cost_detail::ProjectResidual(cost_detail::Transform(cam_q, cam_t, point.cast<T>().eval()), observed, fx, fy,
                                 residual);
    return true;
  }
  static ceres::CostFunction* Create(const Eigen::Vector2d& observed_normalized, const Eigen::Vector3d& point_in_world,
                                     double fx, double fy) {
    return new ceres::AutoDiffCostFunction<FixedPointReprojectionError, 2, 4, 3>(
        new FixedPointReprojectionError(observed_normalized, point_in_world, fx, fy));
  }
  Eigen::Vector2d observed;
  Eigen::Vector3d point;
  double fx, fy;
};

// Corner k of a square tag of known size, the tag a rigid body:
// blocks cam_q, cam_t (cam_from_world), tag_q, tag_t (world_from_tag).
// The size enters as a constant, so the square is exact by construction.
struct TagCornerReprojectionError {
  TagCornerReprojectionError(const Eigen::Vector2d& observed_normalized, const Eigen::Vector3d& corner_in_tag,
                             double fx, double fy)
      : observed(observed_normalized), corner(corner_in_tag), fx(fx), fy(fy) {}
  template <class T>
  bool operator()(const T* cam_q, const T* cam_t, const T* tag_q, const T* tag_t, T* residual) const {
    const Eigen::Matrix<T, 3, 1> in_world = cost_detail::Transform(tag_q, tag_t, corner.cast<T>().eval());
    cost_detail::ProjectResidual(cost_detail::Transform(cam_q, cam_t, in_world), observed, fx, fy, residual);
    return true;
  }
  static ceres::CostFunction* Create(const Eigen::Vector2d& observed_normalized, const Eigen::Vector3d& corner_in_tag,
                                     double fx, double fy) {
    return new ceres::AutoDiffCostFunction<TagCornerReprojectionError, 2, 4, 3, 4, 3>(
        new TagCornerReprojectionError(observed_normalized, corner_in_tag, fx, fy));
  }
  Eigen::Vector2d observed;
  Eigen::Vector3d corner;
  double fx, fy;
};

// All four corners of one tag observation in one block (8 residuals): the
// camera-from-tag transform is computed once instead of four times, and a
// robust loss treats the tag as one unit (a misdetected tag is wrong as a
// whole). Same blocks and geometry as TagCornerReprojectionError.
struct TagReprojectionError {
  TagReprojectionError(const std::array<Eigen::Vector2d, 4>& observed_normalized, double size_m, double fx, double fy)
      : observed(observed_normalized), half(0.5 * size_m), fx(fx), fy(fy) {}
  template <class T>
  bool operator()(const T* cam_q, const T* cam_t, const T* tag_q, const T* tag_t, T* residual) const {
    const Eigen::Map<const Eigen::Quaternion<T>> cam_r(cam_q), tag_r(tag_q);
    const Eigen::Map<const Eigen::Matrix<T, 3, 1>> cam_tr(cam_t), tag_tr(tag_t);
    const Eigen::Matrix<T, 3, 3> r = (cam_r * tag_r).toRotationMatrix();
    const Eigen::Matrix<T, 3, 1> t = cam_r * tag_tr + cam_tr;
    static constexpr double kSigns[4][2] = {{-1, -1}, {1, -1}, {1, 1}, {-1, 1}};
    for (int k = 0; k < 4; ++k) {
      const Eigen::Matrix<T, 3, 1> p = r.col(0) * T(kSigns[k][0] * half) + r.col(1) * T(kSigns[k][1] * half) + t;
      cost_detail::ProjectResidual(p, observed[k], fx, fy, residual + 2 * k);
    }
    return true;
  }
  static ceres::CostFunction* Create(const std::array<Eigen::Vector2d, 4>& observed_normalized, double size_m,
                                     double fx, double fy) {
    return new ceres::AutoDiffCostFunction<TagReprojectionError, 8, 4, 3, 4, 3>(
        new TagReprojectionError(observed_normalized, size_m, fx, fy));
  }
  std::array<Eigen::Vector2d, 4> observed;
  double half, fx, fy;
};

// Pixel-space residuals with the intrinsics as parameters, for refining a
// camera calibrated from the targets: block intrinsics[6] = fx, fy, cx, cy,
// k1, k2 (OpenCV's radial model, no tangential terms).
namespace cost_detail {
template <class T>
void ProjectPixelResidual(const Eigen::Matrix<T, 3, 1>& p, const T* k, const Eigen::Vector2d& observed, T* residual) {
  const T x = p.x() / p.z(), y = p.y() / p.z();
  const T r2 = x * x + y * y;
  const T radial = T(1) + k[4] * r2 + k[5] * r2 * r2;
  residual[0] = k[0] * x * radial + k[2] - T(observed.x());
  residual[1] = k[1] * y * radial + k[3] - T(observed.y());
}
}  // namespace cost_detail

struct TagPixelReprojectionError {
  TagPixelReprojectionError(const std::array<Eigen::Vector2d, 4>& observed_px, double size_m)
      : observed(observed_px), half(0.5 * size_m) {}
  template <class T>
  bool operator()(const T* cam_q, const T* cam_t, const T* tag_q, const T* tag_t, const T* intrinsics,
                  T* residual) const {
    const Eigen::Map<const Eigen::Quaternion<T>> cam_r(cam_q), tag_r(tag_q);
    const Eigen::Map<const Eigen::Matrix<T, 3, 1>> cam_tr(cam_t), tag_tr(tag_t);
    const Eigen::Matrix<T, 3, 3> r = (cam_r * tag_r).toRotationMatrix();
    const Eigen::Matrix<T, 3, 1> t = cam_r * tag_tr + cam_tr;
    static constexpr double kSigns[4][2] = {{-1, -1}, {1, -1}, {1, 1}, {-1, 1}};
    for (int k = 0; k < 4; ++k) {
      const Eigen::Matrix<T, 3, 1> p = r.col(0) * T(kSigns[k][0] * half) + r.col(1) * T(kSigns[k][1] * half) + t;
      cost_detail::ProjectPixelResidual(p, intrinsics, observed[k], residual + 2 * k);
    }
    return true;
  }
  static ceres::CostFunction* Create(const std::array<Eigen::Vector2d, 4>& observed_px, double size_m) {
    return new ceres::AutoDiffCostFunction<TagPixelReprojectionError, 8, 4, 3, 4, 3, 6>(
        new TagPixelReprojectionError(observed_px, size_m));
  }
  std::array<Eigen::Vector2d, 4> observed;
  double half;
};

struct FixedPointPixelReprojectionError {
  FixedPointPixelReprojectionError(const Eigen::Vector2d& observed_px, const Eigen::Vector3d& point_in_world)
      : observed(observed_px), point(point_in_world) {}
  template <class T>
  bool operator()(const T* cam_q, const T* cam_t, const T* intrinsics, T* residual) const {
    cost_detail::ProjectPixelResidual(cost_detail::Transform(cam_q, cam_t, point.cast<T>().eval()), intrinsics,
                                      observed, residual);
    return true;
  }
  static ceres::CostFunction* Create(const Eigen::Vector2d& observed_px, const Eigen::Vector3d& point_in_world) {
    return new ceres::AutoDiffCostFunction<FixedPointPixelReprojectionError, 2, 4, 3, 6>(
        new FixedPointPixelReprojectionError(observed_px, point_in_world));
  }
  Eigen::Vector2d observed;
  Eigen::Vector3d point;
};

// Soft known-size constraint between two free corner points (the relaxed tag
// model): (|a - b| - length) / sigma. Blocks corner_a[3], corner_b[3].
struct TagEdgeLengthError {
  TagEdgeLengthError(double length_m, double sigma_m) : length(length_m), sigma(sigma_m) {}
  template <class T>
  bool operator()(const T* a, const T* b, T* residual) const {
    const Eigen::Matrix<T, 3, 1> d(a[0] - b[0], a[1] - b[1], a[2] - b[2]);
    residual[0] = (d.norm() - T(length)) / T(sigma);
    return true;
  }
  static ceres::CostFunction* Create(double length_m, double sigma_m) {
    return new ceres::AutoDiffCostFunction<TagEdgeLengthError, 1, 3, 3>(new TagEdgeLengthError(length_m, sigma_m));
  }
  double length, sigma;
};

}  // namespace tagsfm
