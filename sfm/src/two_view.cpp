#include "tagsfm/sfm/two_view.h"

#include <algorithm>
#include <cmath>
#include <string>

#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>
#include <opencv2/flann.hpp>

#include "tagsfm/sfm/geometry.h"

namespace tagsfm::sfm {

struct DescriptorIndex::Impl {
  cv::flann::Index index;
};

DescriptorIndex::DescriptorIndex(const cv::Mat& descriptors) : impl_(std::make_unique<Impl>()), rows_(descriptors.rows) {
  // Four randomised k-d trees, searched with 64 checks: within a few percent
  // of brute force's matches on SIFT (Muja & Lowe 2009) at a fraction of the cost.
  if (rows_ >= 2) impl_->index.build(descriptors, cv::flann::KDTreeIndexParams(4), cvflann::FLANN_DIST_L2);
}

DescriptorIndex::~DescriptorIndex() = default;

void DescriptorIndex::Nearest2(const cv::Mat& queries, cv::Mat* indices, cv::Mat* distances) const {
  if (rows_ < 2 || queries.rows == 0) {
    *indices = cv::Mat(queries.rows, 2, CV_32S, cv::Scalar(-1));
    *distances = cv::Mat(queries.rows, 2, CV_32F, cv::Scalar(-1));
    return;
  }
  impl_->index.knnSearch(queries, *indices, *distances, 2, cv::flann::SearchParams(64));
}

namespace {

// best[i] = the match of query i passing the ratio test, or -1.
std::vector<int> RatioBest(const cv::Mat& queries, const DescriptorIndex& index, double ratio) {
  cv::Mat indices, distances;
  index.Nearest2(queries, &indices, &distances);
  std::vector<int> best(queries.rows, -1);
  const double ratio_sq = ratio * ratio;  // distances are squared
  for (int i = 0; i < queries.rows; ++i) {
    const int j = indices.at<int>(i, 0);
    const float d0 = distances.at<float>(i, 0), d1 = distances.at<float>(i, 1);
    if (j >= 0 && indices.at<int>(i, 1) >= 0 && d0 < ratio_sq * d1) best[i] = j;
  }
  return best;
}

}  // namespace

std::vector<FeatureMatch> MatchMutual(const cv::Mat& descriptors_a, const DescriptorIndex& index_a,
                                      const cv::Mat& descriptors_b, const DescriptorIndex& index_b, double ratio) {
  const std::vector<int> a_to_b = RatioBest(descriptors_a, index_b, ratio);
  const std::vector<int> b_to_a = RatioBest(descriptors_b, index_a, ratio);
  std::vector<FeatureMatch> matches;
  for (int i = 0; i < static_cast<int>(a_to_b.size()); ++i) {
    const int j = a_to_b[i];
    if (j >= 0 && j < static_cast<int>(b_to_a.size()) && b_to_a[j] == i) matches.push_back({i, j});
  }
  return matches;
}

Status RelativePoseOptions::Check() const {
  if (!(max_error_px > 0)) return MakeError("sfm.max_error_px must be > 0");
  if (!(focal_px > 0)) return MakeError("sfm: the camera's focal length must be > 0");
  if (!(confidence > 0 && confidence < 1)) return MakeError("sfm.confidence must be in (0, 1)");
  if (min_inliers < 5) return MakeError("sfm.min_inliers must be >= 5 (the five-point solver)");
  return Status::Ok();
}

Result<RelativePose> EstimateRelativePose(const std::vector<Eigen::Vector2d>& normalized_a,
                                          const std::vector<Eigen::Vector2d>& normalized_b,
                                          const RelativePoseOptions& options) {
  if (Status s = options.Check(); !s) return s.error();
  if (normalized_a.size() != normalized_b.size()) return MakeError("relative pose: the two point lists differ in length");
  const int n = static_cast<int>(normalized_a.size());
  if (n < options.min_inliers) {
    return MakeError("relative pose: " + std::to_string(n) + " correspondences, fewer than " +
                     std::to_string(options.min_inliers));
  }
  std::vector<cv::Point2d> pa(n), pb(n);
  for (int i = 0; i < n; ++i) {
    pa[i] = {normalized_a[i].x(), normalized_a[i].y()};
    pb[i] = {normalized_b[i].x(), normalized_b[i].y()};
  }
  cv::Mat mask;
  const cv::Mat eye = cv::Mat::eye(3, 3, CV_64F);
  const cv::Mat e = cv::findEssentialMat(pa, pb, eye, cv::RANSAC, options.confidence,
                                         options.max_error_px / options.focal_px, 1000, mask);
  if (e.rows != 3 || e.cols != 3) return MakeError("relative pose: no essential matrix (degenerate correspondences)");
  cv::Mat r, t;
  // recoverPose keeps the RANSAC inliers in front of both cameras.
  cv::recoverPose(e, pa, pb, eye, r, t, mask);
  Eigen::Matrix3d rotation;
  Eigen::Vector3d translation;
  cv::cv2eigen(r, rotation);
  cv::cv2eigen(t, translation);
  RelativePose out;
  out.cam_b_from_cam_a = Rigid3d(Eigen::Quaterniond(rotation), translation.normalized());
  std::vector<double> angles;
  for (int i = 0; i < n; ++i) {
    if (!mask.at<std::uint8_t>(i)) continue;
    const std::vector<View> views = {{Rigid3d(), normalized_a[i]}, {out.cam_b_from_cam_a, normalized_b[i]}};
    const auto point = TriangulateViews(views);
    if (!point) continue;
    // The inlier threshold again, now on both views' reprojection error.
    const double limit = options.max_error_px / options.focal_px;
    if (ReprojectionError(views[0], *point) > limit || ReprojectionError(views[1], *point) > limit) continue;
    out.inliers.push_back(i);
    angles.push_back(MaxTriangulationAngleDeg(views, *point));
  }
  if (static_cast<int>(out.inliers.size()) < options.min_inliers) {
    return MakeError("relative pose: " + std::to_string(out.inliers.size()) + " inliers of " + std::to_string(n) +
                     ", fewer than " + std::to_string(options.min_inliers));
  }
  std::nth_element(angles.begin(), angles.begin() + angles.size() / 2, angles.end());
  out.median_angle_deg = angles[angles.size() / 2];
  return out;
}

}  // namespace tagsfm::sfm
