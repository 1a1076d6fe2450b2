#pragma once
// Two views without poses: descriptor matching (ratio test, mutual best) and
// the relative pose from the essential matrix (RANSAC, known intrinsics), as
// COLMAP's matcher and two-view geometry verification do.
#include <memory>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "tagsfm/core/result.h"
#include "tagsfm/core/rigid3d.h"

namespace tagsfm::sfm {

struct FeatureMatch {
  int a = -1, b = -1;  // feature indices in the two views
};

// Nearest-neighbour search over one view's descriptors, built once per view
// and queried by every other view (FLANN k-d trees: exhaustive matching of
// 10k x 10k SIFT descriptors costs seconds per pair).
class DescriptorIndex {
 public:
  explicit DescriptorIndex(const cv::Mat& descriptors);  // CV_32F rows, kept by reference
  ~DescriptorIndex();
  DescriptorIndex(const DescriptorIndex&) = delete;
  DescriptorIndex& operator=(const DescriptorIndex&) = delete;
  // Per query row: the two nearest rows' indices and squared L2 distances (-1 when fewer).
  void Nearest2(const cv::Mat& queries, cv::Mat* indices, cv::Mat* distances) const;
  int size() const { return rows_; }

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  int rows_ = 0;
};

// Lowe's ratio test (nearest / second nearest distance < ratio) in both
// directions, and only pairs that are each other's nearest neighbour.
std::vector<FeatureMatch> MatchMutual(const cv::Mat& descriptors_a, const DescriptorIndex& index_a,
                                      const cv::Mat& descriptors_b, const DescriptorIndex& index_b, double ratio);

struct RelativePoseOptions {
  double max_error_px = 4.0;   // RANSAC inlier threshold (COLMAP's two_view max_error)
  double focal_px = 1000.0;    // turns max_error_px into normalised units
  double confidence = 0.999;
  int min_inliers = 15;        // COLMAP's min_num_inliers
  Status Check() const;
};

struct RelativePose {
  Rigid3d cam_b_from_cam_a;      // |translation| = 1: two views have no scale
  std::vector<int> inliers;      // indices into the given correspondences, cheirality checked
  double median_angle_deg = 0;   // triangulation angle of the inliers
};

// Essential-matrix RANSAC on undistorted normalised points (x/z, y/z),
// decomposed with the cheirality test. An error when there are too few
// correspondences or inliers.
Result<RelativePose> EstimateRelativePose(const std::vector<Eigen::Vector2d>& normalized_a,
                                          const std::vector<Eigen::Vector2d>& normalized_b,
                                          const RelativePoseOptions& options);

}  // namespace tagsfm::sfm
