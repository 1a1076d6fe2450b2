#include "tagsfm/sfm/geometry.h"

#include <cmath>
#include <limits>
#include <string>

#include <Eigen/Dense>
#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>

namespace tagsfm::sfm {

double ReprojectionError(const View& view, const Eigen::Vector3d& point) {
  const Eigen::Vector3d p = view.cam_from_world * point;
  if (!(p.z() > 1e-12)) return std::numeric_limits<double>::infinity();
  return (p.head<2>() / p.z() - view.normalized).norm();
}

double MaxTriangulationAngleDeg(const std::vector<View>& views, const Eigen::Vector3d& point) {
  double max_angle = 0;
  for (size_t i = 0; i < views.size(); ++i) {
    const Eigen::Vector3d ri = (point - views[i].cam_from_world.Center()).normalized();
    for (size_t j = i + 1; j < views.size(); ++j) {
      const Eigen::Vector3d rj = (point - views[j].cam_from_world.Center()).normalized();
      max_angle = std::max(max_angle, std::acos(std::clamp(ri.dot(rj), -1.0, 1.0)));
    }
  }
  return max_angle * 180.0 / M_PI;
}

std::optional<Eigen::Vector3d> TriangulateViews(const std::vector<View>& views) {
  if (views.size() < 2) return std::nullopt;
  Eigen::MatrixXd a(2 * views.size(), 4);
  for (size_t i = 0; i < views.size(); ++i) {
    Eigen::Matrix<double, 3, 4> p;
    p.leftCols<3>() = views[i].cam_from_world.RotationMatrix();
    p.col(3) = views[i].cam_from_world.translation;
    a.row(2 * i) = views[i].normalized.x() * p.row(2) - p.row(0);
    a.row(2 * i + 1) = views[i].normalized.y() * p.row(2) - p.row(1);
  }
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(a, Eigen::ComputeFullV);
  const Eigen::Vector4d h = svd.matrixV().col(3);
  if (std::abs(h(3)) < 1e-12) return std::nullopt;
  Eigen::Vector3d x = h.head<3>() / h(3);
  // Gauss-Newton on the reprojection error: the DLT minimises an algebraic
  // error that weights views by depth.
  for (int iteration = 0; iteration < 5; ++iteration) {
    Eigen::Matrix3d jtj = Eigen::Matrix3d::Zero();
    Eigen::Vector3d jtr = Eigen::Vector3d::Zero();
    for (const View& v : views) {
      const Eigen::Matrix3d r = v.cam_from_world.RotationMatrix();
      const Eigen::Vector3d p = r * x + v.cam_from_world.translation;
      if (p.z() <= 1e-12) return x;  // behind a camera: the caller's cheirality check rejects it
      Eigen::Matrix<double, 2, 3> dproj;
      dproj << 1 / p.z(), 0, -p.x() / (p.z() * p.z()), 0, 1 / p.z(), -p.y() / (p.z() * p.z());
      const Eigen::Matrix<double, 2, 3> j = dproj * r;
      const Eigen::Vector2d res = p.head<2>() / p.z() - v.normalized;
      jtj += j.transpose() * j;
      jtr += j.transpose() * res;
    }
    const Eigen::Vector3d step = jtj.ldlt().solve(-jtr);
    if (!step.allFinite()) break;
    x += step;
    if (step.norm() < 1e-12 * (1 + x.norm())) break;
  }
  if (!x.allFinite()) return std::nullopt;
  return x;
}

Status AbsolutePoseOptions::Check() const {
  if (!(max_error_px > 0)) return MakeError("sfm.abs_pose_max_error_px must be > 0");
  if (!(focal_px > 0)) return MakeError("sfm: the camera's focal length must be > 0");
  if (min_inliers < 4) return MakeError("sfm.abs_pose_min_inliers must be >= 4");
  if (!(min_inlier_ratio >= 0 && min_inlier_ratio <= 1)) return MakeError("sfm.abs_pose_min_inlier_ratio must be in [0, 1]");
  return Status::Ok();
}

Result<AbsolutePose> EstimateAbsolutePose(const std::vector<Eigen::Vector3d>& points_in_world,
                                          const std::vector<Eigen::Vector2d>& normalized,
                                          const AbsolutePoseOptions& options) {
  if (Status s = options.Check(); !s) return s.error();
  const int n = static_cast<int>(points_in_world.size());
  if (n != static_cast<int>(normalized.size())) return MakeError("absolute pose: the 2D and 3D lists differ in length");
  if (n < options.min_inliers) {
    return MakeError(std::to_string(n) + " 2D-3D correspondences, fewer than " + std::to_string(options.min_inliers));
  }
  std::vector<cv::Point3d> object(n);
  std::vector<cv::Point2d> image(n);
  for (int i = 0; i < n; ++i) {
    object[i] = {points_in_world[i].x(), points_in_world[i].y(), points_in_world[i].z()};
    image[i] = {normalized[i].x(), normalized[i].y()};
  }
  const cv::Mat eye = cv::Mat::eye(3, 3, CV_64F);
  const double threshold = options.max_error_px / options.focal_px;
  cv::Mat rvec, tvec;
  std::vector<int> ransac_inliers;
  const bool found = cv::solvePnPRansac(object, image, eye, cv::noArray(), rvec, tvec, false, 1000, threshold, 0.9999,
                                        ransac_inliers, cv::SOLVEPNP_AP3P);
  if (!found || static_cast<int>(ransac_inliers.size()) < options.min_inliers) {
    return MakeError("PnP: " + std::to_string(ransac_inliers.size()) + " inliers of " + std::to_string(n) +
                     " 2D-3D correspondences, fewer than " + std::to_string(options.min_inliers));
  }
  std::vector<cv::Point3d> in_object;
  std::vector<cv::Point2d> in_image;
  for (int i : ransac_inliers) {
    in_object.push_back(object[i]);
    in_image.push_back(image[i]);
  }
  cv::solvePnPRefineLM(in_object, in_image, eye, cv::noArray(), rvec, tvec);
  cv::Mat r;
  cv::Rodrigues(rvec, r);
  Eigen::Matrix3d rotation;
  Eigen::Vector3d translation;
  cv::cv2eigen(r, rotation);
  cv::cv2eigen(tvec, translation);
  AbsolutePose out;
  out.cam_from_world = Rigid3d(Eigen::Quaterniond(rotation), translation);
  for (int i = 0; i < n; ++i) {
    if (ReprojectionError({out.cam_from_world, normalized[i]}, points_in_world[i]) <= threshold) out.inliers.push_back(i);
  }
  const int inliers = static_cast<int>(out.inliers.size());
  if (inliers < options.min_inliers || inliers < options.min_inlier_ratio * n) {
    return MakeError("PnP: " + std::to_string(inliers) + " inliers of " + std::to_string(n) +
                     " 2D-3D correspondences after refinement, too few");
  }
  return out;
}

}  // namespace tagsfm::sfm
