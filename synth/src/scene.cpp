#include "tagsfm/synth/scene.h"

#include <algorithm>
#include <cmath>

namespace tagsfm::synth {

double Rectangle3d::DistanceTo(const Eigen::Vector3d& point) const {
  const Eigen::Vector3d d = point - origin;
  const double a = std::clamp(d.dot(edge_u) / edge_u.squaredNorm(), 0.0, 1.0);
  const double b = std::clamp(d.dot(edge_v) / edge_v.squaredNorm(), 0.0, 1.0);
  return (origin + a * edge_u + b * edge_v - point).norm();
}

TagCorners TagCornersInWorld(const Scene& scene, const PlacedTag& tag) {
  const Rectangle3d& rect = scene.faces[static_cast<size_t>(tag.face)].rect;
  const Eigen::Vector2d right(std::cos(tag.angle_rad), std::sin(tag.angle_rad));
  const Eigen::Vector2d up(-right.y(), right.x());
  const double h = tag.size_m / 2;
  // libapriltag's order on the upright tag: bottom-left, bottom-right,
  // top-right, top-left (verified against its detector in tests/synth).
  const Eigen::Vector2d local[4] = {{-h, -h}, {h, -h}, {h, h}, {-h, h}};
  TagCorners corners;
  for (int i = 0; i < 4; ++i) {
    corners[static_cast<size_t>(i)] = rect.PointAt(tag.centre_in_face + local[i].x() * right + local[i].y() * up);
  }
  return corners;
}

TargetCornerMap SceneTargets(const Scene& scene) {
  TargetCornerMap targets;
  for (const PlacedTag& tag : scene.tags) targets[tag.id] = TagCornersInWorld(scene, tag);
  return targets;
}

}  // namespace tagsfm::synth
