#include "tagsfm/recon/tag_geometry.h"

#include <Eigen/SVD>

namespace tagsfm {

Eigen::Vector3d TagCornerInTag(int corner, double size_m) {
  const double h = 0.5 * size_m;
  switch (corner) {
    case 0: return {-h, -h, 0};
    case 1: return {h, -h, 0};
    case 2: return {h, h, 0};
    default: return {-h, h, 0};
  }
}

TagCorners TagCornersInTag(double size_m) {
  return {TagCornerInTag(0, size_m), TagCornerInTag(1, size_m), TagCornerInTag(2, size_m), TagCornerInTag(3, size_m)};
}

TagCorners TagCornersInWorld(const Rigid3d& world_from_tag, double size_m) {
  TagCorners out;
  for (int k = 0; k < 4; ++k) out[k] = world_from_tag * TagCornerInTag(k, size_m);
  return out;
}

Eigen::Vector3d TagCenter(const TagCorners& corners) {
  return 0.25 * (corners[0] + corners[1] + corners[2] + corners[3]);
}

std::array<double, 4> TagEdgeLengths(const TagCorners& corners) {
  std::array<double, 4> out{};
  for (int k = 0; k < 4; ++k) out[k] = (corners[(k + 1) % 4] - corners[k]).norm();
  return out;
}

Rigid3d FitTagPose(const TagCorners& corners_in_world, double size_m) {
  // Kabsch: the rotation taking the centred model square onto the centred
  // measured corners; the model's centre is the origin.
  const Eigen::Vector3d centre = TagCenter(corners_in_world);
  Eigen::Matrix3d cross = Eigen::Matrix3d::Zero();
  for (int k = 0; k < 4; ++k) cross += (corners_in_world[k] - centre) * TagCornerInTag(k, size_m).transpose();
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(cross, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d fix = Eigen::Matrix3d::Identity();
  if ((svd.matrixU() * svd.matrixV().transpose()).determinant() < 0) fix(2, 2) = -1;
  const Eigen::Matrix3d rotation = svd.matrixU() * fix * svd.matrixV().transpose();
  return Rigid3d(Eigen::Quaterniond(rotation), centre);
}

}  // namespace tagsfm
