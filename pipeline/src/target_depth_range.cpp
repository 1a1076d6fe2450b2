#include <algorithm>

#include "tagsfm/pipeline/feature_stage.h"

namespace tagsfm {

std::optional<DepthRange> TargetDepthRange(const TargetCornerMap& corners, const Rigid3d& cam_from_world,
                                           const CameraModel& camera, double factor) {
  std::vector<double> depths;
  for (const auto& [id, tag] : corners) {
    for (const Eigen::Vector3d& corner : tag) {
      const Eigen::Vector3d x = cam_from_world * corner;
      if (!(x.z() > 0)) continue;
      const Eigen::Vector2d p = camera.Project(x);
      if (p.x() < -0.5 || p.y() < -0.5 || p.x() > camera.width - 0.5 || p.y() > camera.height - 0.5) continue;
      depths.push_back(x.z());
    }
  }
  if (depths.empty()) return std::nullopt;
  auto middle = depths.begin() + static_cast<long>(depths.size() / 2);
  std::nth_element(depths.begin(), middle, depths.end());
  return DepthRange::Around(*middle, factor);
}

}  // namespace tagsfm
