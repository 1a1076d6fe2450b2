#pragma once
// The residuals of the adjustment, one small functor per kind. Observations
// are undistorted to normalised image coordinates once (CameraModel::
// PixelsToNormalized), and residuals are scaled back by fx, fy so they read
// in pixels. Poses are PoseParams blocks of 7: quaternion (x, y, z, w),
// then translation.
#include <ceres/autodiff_cost_function.h>
#include <ceres/manifold.h>
#include <ceres/product_manifold.h>
#include <ceres/rotation.h>

#include <array>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace tagsfm {

// The manifold of a PoseParams block: the quaternion's (Ceres'
// EigenQuaternionManifold: exp of the tangent applied on the left) times
// R^3; tangent [rotation (3), translation (3)].
using PoseManifold = ceres::ProductManifold<ceres::EigenQuaternionManifold, ceres::EuclideanManifold<3>>;

namespace cost_detail {
template <class T>
Eigen::Matrix<T, 3, 1> Transform(const T* pose, const Eigen::Matrix<T, 3, 1>& point) {
  const Eigen::Map<const Eigen::Quaternion<T>> rotation(pose);
  const Eigen::Map<const Eigen::Matrix<T, 3, 1>> translation(pose + 4);
  return rotation * point + translation;
}
// camera-from-tag = camera-from-world * world-from-tag, as rotation matrix and translation.
template <class T>
void Compose(const T* cam_from_world, const T* world_from_tag, Eigen::Matrix<T, 3, 3>* r, Eigen::Matrix<T, 3, 1>* t) {
  const Eigen::Map<const Eigen::Quaternion<T>> cam_r(cam_from_world), tag_r(world_from_tag);
  const Eigen::Map<const Eigen::Matrix<T, 3, 1>> cam_t(cam_from_world + 4), tag_t(world_from_tag + 4);
  *r = (cam_r * tag_r).toRotationMatrix();
  *t = cam_r * tag_t + cam_t;
}
template <class T>
void ProjectResidual(const Eigen::Matrix<T, 3, 1>& point_in_cam, const Eigen::Vector2d& observed, double fx, double fy,
                     T* residual) {
  residual[0] = T(fx) * (point_in_cam.x() / point_in_cam.z() - T(observed.x()));
  residual[1] = T(fy) * (point_in_cam.y() / point_in_cam.z() - T(observed.y()));
}
// A corner's 2-vector residual times its weight (corner_weights.h).
template <class T>
void Whiten(const Eigen::Matrix2d& weight, T* residual) {
  const T r0 = residual[0], r1 = residual[1];
  residual[0] = T(weight(0, 0)) * r0 + T(weight(0, 1)) * r1;
  residual[1] = T(weight(1, 0)) * r0 + T(weight(1, 1)) * r1;
}
using CornerWeights = std::array<Eigen::Matrix2d, 4>;
inline CornerWeights Unweighted() {
  return {Eigen::Matrix2d::Identity(), Eigen::Matrix2d::Identity(), Eigen::Matrix2d::Identity(),
          Eigen::Matrix2d::Identity()};
}
}  // namespace cost_detail

// A free 3D point seen by a camera: blocks cam_from_world[7], point_in_world[3].
struct ReprojectionError {
  ReprojectionError(const Eigen::Vector2d& observed_normalized, double fx, double fy)
      : observed(observed_normalized), fx(fx), fy(fy) {}
  template <class T>
  bool operator()(const T* cam_from_world, const T* point, T* residual) const {
    const Eigen::Matrix<T, 3, 1> p(point[0], point[1], point[2]);
    cost_detail::ProjectResidual(cost_detail::Transform(cam_from_world, p), observed, fx, fy, residual);
    return true;
  }
  static ceres::CostFunction* Create(const Eigen::Vector2d& observed_normalized, double fx, double fy) {
    return new ceres::AutoDiffCostFunction<ReprojectionError, 2, 7, 3>(
        new ReprojectionError(observed_normalized, fx, fy));
  }
  Eigen::Vector2d observed;
  double fx, fy;
};

// A point held fixed (a known-map corner) seen by a camera, the residual
// times `weight` (corner_weights.h): block cam_from_world.
struct FixedPointReprojectionError {
  FixedPointReprojectionError(const Eigen::Vector2d& observed_normalized, const Eigen::Vector3d& point_in_world,
                              double fx, double fy, const Eigen::Matrix2d& weight = Eigen::Matrix2d::Identity())
      : observed(observed_normalized), point(point_in_world), fx(fx), fy(fy), weight(weight) {}
  template <class T>
  bool operator()(const T* cam_from_world, T* residual) const {
    cost_detail::ProjectResidual(cost_detail::Transform(cam_from_world, point.cast<T>().eval()), observed, fx, fy,
                                 residual);
    cost_detail::Whiten(weight, residual);
    return true;
  }
  static ceres::CostFunction* Create(const Eigen::Vector2d& observed_normalized, const Eigen::Vector3d& point_in_world,
                                     double fx, double fy,
                                     const Eigen::Matrix2d& weight = Eigen::Matrix2d::Identity()) {
    return new ceres::AutoDiffCostFunction<FixedPointReprojectionError, 2, 7>(
        new FixedPointReprojectionError(observed_normalized, point_in_world, fx, fy, weight));
  }
  Eigen::Vector2d observed;
  Eigen::Vector3d point;
  double fx, fy;
  Eigen::Matrix2d weight;
};

// Corner k of a square tag of known size, the tag a rigid body:
// blocks cam_from_world, world_from_tag.
// The size enters as a constant, so the square is exact by construction.
struct TagCornerReprojectionError {
  TagCornerReprojectionError(const Eigen::Vector2d& observed_normalized, const Eigen::Vector3d& corner_in_tag,
                             double fx, double fy)
      : observed(observed_normalized), corner(corner_in_tag), fx(fx), fy(fy) {}
  template <class T>
  bool operator()(const T* cam_from_world, const T* world_from_tag, T* residual) const {
    const Eigen::Matrix<T, 3, 1> in_world = cost_detail::Transform(world_from_tag, corner.cast<T>().eval());
    cost_detail::ProjectResidual(cost_detail::Transform(cam_from_world, in_world), observed, fx, fy, residual);
    return true;
  }
  static ceres::CostFunction* Create(const Eigen::Vector2d& observed_normalized, const Eigen::Vector3d& corner_in_tag,
                                     double fx, double fy) {
    return new ceres::AutoDiffCostFunction<TagCornerReprojectionError, 2, 7, 7>(
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
  TagReprojectionError(const std::array<Eigen::Vector2d, 4>& observed_normalized, double size_m, double fx, double fy,
                       const cost_detail::CornerWeights& weights = cost_detail::Unweighted())
      : observed(observed_normalized), half(0.5 * size_m), fx(fx), fy(fy), weights(weights) {}
  template <class T>
  bool operator()(const T* cam_from_world, const T* world_from_tag, T* residual) const {
    Eigen::Matrix<T, 3, 3> r;
    Eigen::Matrix<T, 3, 1> t;
    cost_detail::Compose(cam_from_world, world_from_tag, &r, &t);
    static constexpr double kSigns[4][2] = {{-1, -1}, {1, -1}, {1, 1}, {-1, 1}};
    for (int k = 0; k < 4; ++k) {
      const Eigen::Matrix<T, 3, 1> p = r.col(0) * T(kSigns[k][0] * half) + r.col(1) * T(kSigns[k][1] * half) + t;
      cost_detail::ProjectResidual(p, observed[k], fx, fy, residual + 2 * k);
      cost_detail::Whiten(weights[k], residual + 2 * k);
    }
    return true;
  }
  // `weights`: each corner's (corner_weights.h), none by default.
  static ceres::CostFunction* Create(const std::array<Eigen::Vector2d, 4>& observed_normalized, double size_m,
                                     double fx, double fy,
                                     const cost_detail::CornerWeights& weights = cost_detail::Unweighted()) {
    return new ceres::AutoDiffCostFunction<TagReprojectionError, 8, 7, 7>(
        new TagReprojectionError(observed_normalized, size_m, fx, fy, weights));
  }
  std::array<Eigen::Vector2d, 4> observed;
  double half, fx, fy;
  cost_detail::CornerWeights weights;
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
  TagPixelReprojectionError(const std::array<Eigen::Vector2d, 4>& observed_px, double size_m,
                            const cost_detail::CornerWeights& weights = cost_detail::Unweighted())
      : observed(observed_px), half(0.5 * size_m), weights(weights) {}
  template <class T>
  bool operator()(const T* cam_from_world, const T* world_from_tag, const T* intrinsics, T* residual) const {
    Eigen::Matrix<T, 3, 3> r;
    Eigen::Matrix<T, 3, 1> t;
    cost_detail::Compose(cam_from_world, world_from_tag, &r, &t);
    static constexpr double kSigns[4][2] = {{-1, -1}, {1, -1}, {1, 1}, {-1, 1}};
    for (int k = 0; k < 4; ++k) {
      const Eigen::Matrix<T, 3, 1> p = r.col(0) * T(kSigns[k][0] * half) + r.col(1) * T(kSigns[k][1] * half) + t;
      cost_detail::ProjectPixelResidual(p, intrinsics, observed[k], residual + 2 * k);
      cost_detail::Whiten(weights[k], residual + 2 * k);
    }
    return true;
  }
  static ceres::CostFunction* Create(const std::array<Eigen::Vector2d, 4>& observed_px, double size_m,
                                     const cost_detail::CornerWeights& weights = cost_detail::Unweighted()) {
    return new ceres::AutoDiffCostFunction<TagPixelReprojectionError, 8, 7, 7, 6>(
        new TagPixelReprojectionError(observed_px, size_m, weights));
  }
  std::array<Eigen::Vector2d, 4> observed;
  double half;
  cost_detail::CornerWeights weights;
};

struct FixedPointPixelReprojectionError {
  FixedPointPixelReprojectionError(const Eigen::Vector2d& observed_px, const Eigen::Vector3d& point_in_world,
                                   const Eigen::Matrix2d& weight = Eigen::Matrix2d::Identity())
      : observed(observed_px), point(point_in_world), weight(weight) {}
  template <class T>
  bool operator()(const T* cam_from_world, const T* intrinsics, T* residual) const {
    cost_detail::ProjectPixelResidual(cost_detail::Transform(cam_from_world, point.cast<T>().eval()), intrinsics,
                                      observed, residual);
    cost_detail::Whiten(weight, residual);
    return true;
  }
  static ceres::CostFunction* Create(const Eigen::Vector2d& observed_px, const Eigen::Vector3d& point_in_world,
                                     const Eigen::Matrix2d& weight = Eigen::Matrix2d::Identity()) {
    return new ceres::AutoDiffCostFunction<FixedPointPixelReprojectionError, 2, 7, 6>(
        new FixedPointPixelReprojectionError(observed_px, point_in_world, weight));
  }
  Eigen::Vector2d observed;
  Eigen::Vector3d point;
  Eigen::Matrix2d weight;
};

// A free point seen by a camera whose intrinsics are adjusted, the residual
// scaled by `weight`: blocks cam_from_world[7], point[3], intrinsics[6].
struct PointPixelReprojectionError {
  PointPixelReprojectionError(const Eigen::Vector2d& observed_px, double weight) : observed(observed_px), weight(weight) {}
  template <class T>
  bool operator()(const T* cam_from_world, const T* point, const T* intrinsics, T* residual) const {
    const Eigen::Matrix<T, 3, 1> p(point[0], point[1], point[2]);
    cost_detail::ProjectPixelResidual(cost_detail::Transform(cam_from_world, p), intrinsics, observed, residual);
    residual[0] *= T(weight);
    residual[1] *= T(weight);
    return true;
  }
  static ceres::CostFunction* Create(const Eigen::Vector2d& observed_px, double weight) {
    return new ceres::AutoDiffCostFunction<PointPixelReprojectionError, 2, 7, 3, 6>(
        new PointPixelReprojectionError(observed_px, weight));
  }
  Eigen::Vector2d observed;
  double weight;
};

// Square pixels as a stiff pseudo-observation on the adjusted intrinsics
// (fx - fy) / sigma: with sigma far below any pixel's noise, fy follows fx,
// and the covariance keeps its six columns. Block intrinsics[6].
struct SquarePixelTie {
  explicit SquarePixelTie(double sigma_px) : sigma(sigma_px) {}
  template <class T>
  bool operator()(const T* intrinsics, T* residual) const {
    residual[0] = (intrinsics[0] - intrinsics[1]) / T(sigma);
    return true;
  }
  static ceres::CostFunction* Create(double sigma_px) {
    return new ceres::AutoDiffCostFunction<SquarePixelTie, 1, 6>(new SquarePixelTie(sigma_px));
  }
  double sigma;
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
