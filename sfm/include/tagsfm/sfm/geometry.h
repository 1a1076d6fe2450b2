#pragma once
// Multi-view triangulation with COLMAP's checks (triangulation angle,
// cheirality, reprojection), and camera registration by PnP RANSAC on 2D-3D
// correspondences. Image points are undistorted normalised coordinates.
#include <optional>
#include <vector>

#include <Eigen/Core>

#include "tagsfm/core/result.h"
#include "tagsfm/core/rigid3d.h"

namespace tagsfm::sfm {

struct View {
  Rigid3d cam_from_world;
  Eigen::Vector2d normalized = Eigen::Vector2d::Zero();
};

// Linear triangulation (DLT over all views) refined by Gauss-Newton on the
// reprojection error; nullopt when the system is degenerate.
std::optional<Eigen::Vector3d> TriangulateViews(const std::vector<View>& views);

// Largest angle between the rays of any two views at the point, degrees.
double MaxTriangulationAngleDeg(const std::vector<View>& views, const Eigen::Vector3d& point);

// Reprojection error of the point in one view, in normalised units
// (multiply by the focal length for pixels); infinity behind the camera.
double ReprojectionError(const View& view, const Eigen::Vector3d& point);

struct AbsolutePoseOptions {
  double max_error_px = 12.0;  // RANSAC threshold (COLMAP's abs_pose_max_error)
  double focal_px = 1000.0;
  int min_inliers = 30;        // COLMAP's abs_pose_min_num_inliers
  double min_inlier_ratio = 0.25;
  Status Check() const;
};

struct AbsolutePose {
  Rigid3d cam_from_world;
  std::vector<int> inliers;  // indices into the correspondences
};

// PnP RANSAC (P3P), refined by Levenberg-Marquardt on the inliers.
Result<AbsolutePose> EstimateAbsolutePose(const std::vector<Eigen::Vector3d>& points_in_world,
                                          const std::vector<Eigen::Vector2d>& normalized,
                                          const AbsolutePoseOptions& options);

}  // namespace tagsfm::sfm
