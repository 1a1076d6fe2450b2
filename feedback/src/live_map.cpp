#include "tagsfm/feedback/live_map.h"

namespace tagsfm {

void LiveMapTracker::Add(const FrameReport& report, const std::vector<TagSighting>& views) {
  if (!report.registered) {
    map_.camera_in_world.reset();
    map_.camera_axis_in_world.reset();
    return;
  }
  const Rigid3d world_from_cam = report.cam_from_world.Inverse();
  const Eigen::Vector3d centre = world_from_cam.translation;
  map_.camera_in_world = centre;
  map_.camera_axis_in_world = world_from_cam.rotation * Eigen::Vector3d::UnitZ();
  for (const TagSighting& view : views) {
    // Eigen leaves a default-constructed vector uninitialised: start at zero.
    auto [it, added] = sums_.try_emplace(view.id, Eigen::Vector3d::Zero(), 0);
    it->second.first += world_from_cam * view.centre_in_cam;
    ++it->second.second;
  }
  map_.targets.clear();
  for (const auto& [id, entry] : sums_) map_.targets.push_back({id, entry.first / entry.second});
  AddToPath(centre);
  UpdateTopAxes(report.cam_from_world);
}

// Every path_stride_-th registered frame; when the path is full, every other
// point goes and the stride doubles, so the path stays even in time.
void LiveMapTracker::AddToPath(const Eigen::Vector3d& centre) {
  if (registered_++ % path_stride_ != 0) return;
  map_.camera_path.push_back(centre);
  if (map_.camera_path.size() < kMaxCameraPathPoints) return;
  std::vector<Eigen::Vector3d> thinned;
  thinned.reserve(kMaxCameraPathPoints / 2 + 1);
  for (size_t i = 0; i < map_.camera_path.size(); i += 2) thinned.push_back(map_.camera_path[i]);
  map_.camera_path = std::move(thinned);
  path_stride_ *= 2;
}

void LiveMapTracker::UpdateTopAxes(const Rigid3d& cam_from_world) {
  const Eigen::Matrix3d world_from_cam = cam_from_world.RotationMatrix().transpose();
  up_sum_ -= world_from_cam.col(1);  // image y points down
  if (!first_right_) first_right_ = world_from_cam.col(0);
  if (!(up_sum_.norm() > 0)) return;
  const Eigen::Vector3d up = up_sum_.normalized();
  Eigen::Vector3d x = *first_right_ - first_right_->dot(up) * up;
  if (x.norm() < 1e-6) x = up.unitOrthogonal();  // the first camera looked straight down
  map_.top_x = x.normalized();
  // Right-handed seen from above: x to the right, y away from the viewer.
  map_.top_y = up.cross(map_.top_x);
}

}  // namespace tagsfm
