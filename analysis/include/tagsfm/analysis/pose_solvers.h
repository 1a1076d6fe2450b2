#pragma once
// The pose solvers the sweeps compare: the paper's EPnP alone, EPnP refined
// by Levenberg-Marquardt (the maximum-likelihood pose), and this project's
// own estimator (recon/pose_estimator.h: RANSAC EPnP, checks, robust LM).
#include <string>
#include <vector>

#include <Eigen/Core>

#include "tagsfm/core/camera_model.h"
#include "tagsfm/core/rigid3d.h"

namespace tagsfm::analysis {

enum class PoseSolver { kEpnp, kEpnpLm, kPipeline };
const char* PoseSolverName(PoseSolver solver);

struct SolvedPose {
  bool ok = false;
  std::string reason;  // why not, when !ok
  Rigid3d cam_from_world;
};

// Pose from 2D-3D correspondences (pixels of a distortion-free camera).
SolvedPose SolvePose(PoseSolver solver, const std::vector<Eigen::Vector3d>& points_in_world,
                     const std::vector<Eigen::Vector2d>& pixels, const CameraModel& camera);

}  // namespace tagsfm::analysis
