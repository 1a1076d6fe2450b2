#pragma once
// features.csv, a result file beside cloud.ply: every feature point with its
// id (as in cloud.ply's order and colmap/points3D.txt), position, colour,
// track length, reprojection RMS and covariance, so that `tagsfm measure`
// can give a feature point's distances with their standard deviation.
#include <filesystem>
#include <map>

#include <Eigen/Core>

#include "tagsfm/core/result.h"
#include "tagsfm/feature/feature_triangulation.h"

namespace tagsfm {

struct StoredFeaturePoint {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
  int track_length = 0;
  double reprojection_rms_px = 0;
};

// Point i of `points` gets id first_id + i.
Status WriteFeaturePointsCsv(const std::filesystem::path& path, const std::vector<FeaturePoint>& points,
                             long long first_id);
Result<std::map<long long, StoredFeaturePoint>> ReadFeaturePointsCsv(const std::filesystem::path& path);

}  // namespace tagsfm
