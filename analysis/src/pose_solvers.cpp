#include "tagsfm/analysis/pose_solvers.h"

#include <optional>

#include <Eigen/Geometry>
#include <opencv2/calib3d.hpp>

#include "tagsfm/recon/pose_estimator.h"

namespace tagsfm::analysis {
namespace {

Rigid3d FromRvecTvec(const cv::Mat& rvec, const cv::Mat& tvec) {
  cv::Matx33d r;
  cv::Rodrigues(rvec, r);
  Eigen::Matrix3d rotation;
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) rotation(i, j) = r(i, j);
  }
  return Rigid3d(Eigen::Quaterniond(rotation), Eigen::Vector3d(tvec.at<double>(0), tvec.at<double>(1), tvec.at<double>(2)));
}

SolvedPose SolveWithOpenCv(bool refine, const std::vector<Eigen::Vector3d>& points_in_world,
                           const std::vector<Eigen::Vector2d>& pixels, const CameraModel& camera) {
  std::vector<cv::Point3d> object;
  std::vector<cv::Point2d> image;
  object.reserve(points_in_world.size());
  image.reserve(pixels.size());
  for (const Eigen::Vector3d& p : points_in_world) object.emplace_back(p.x(), p.y(), p.z());
  for (const Eigen::Vector2d& p : pixels) image.emplace_back(p.x(), p.y());
  cv::Mat rvec, tvec;
  try {  // OpenCV reports degenerate input by exception; keep it inside the module
    if (!cv::solvePnP(object, image, camera.K(), cv::noArray(), rvec, tvec, false, cv::SOLVEPNP_EPNP)) {
      return {false, "EPnP failed", {}};
    }
    if (refine) cv::solvePnPRefineLM(object, image, camera.K(), cv::noArray(), rvec, tvec);
  } catch (const cv::Exception& e) {
    return {false, std::string("EPnP: ") + e.what(), {}};
  }
  const Rigid3d pose = FromRvecTvec(rvec, tvec);
  if (!pose.translation.allFinite() || !pose.rotation.coeffs().allFinite()) return {false, "EPnP: non-finite pose", {}};
  return {true, "", pose};
}

}  // namespace

const char* PoseSolverName(PoseSolver solver) {
  switch (solver) {
    case PoseSolver::kEpnp: return "EPnP";
    case PoseSolver::kEpnpLm: return "EPnP+LM";
    case PoseSolver::kPipeline: return "tagsfm";
  }
  return "?";
}

SolvedPose SolvePose(PoseSolver solver, const std::vector<Eigen::Vector3d>& points_in_world,
                     const std::vector<Eigen::Vector2d>& pixels, const CameraModel& camera) {
  if (points_in_world.size() < 4 || points_in_world.size() != pixels.size()) {
    return {false, "fewer than 4 correspondences", {}};
  }
  if (solver != PoseSolver::kPipeline) {
    return SolveWithOpenCv(solver == PoseSolver::kEpnpLm, points_in_world, pixels, camera);
  }
  const PoseResult result = EstimatePose(points_in_world, camera.PixelsToNormalized(pixels), camera.fx, camera.fy,
                                         std::nullopt, PoseEstimatorOptions());
  if (!result.registered) return {false, result.reason, {}};
  return {true, "", result.cam_from_world};
}

}  // namespace tagsfm::analysis
