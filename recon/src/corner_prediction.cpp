#include "tagsfm/recon/corner_prediction.h"

#include <algorithm>
#include <array>
#include <cmath>

#include <Eigen/Geometry>

namespace tagsfm {

Status CornerPredictionOptions::Check() const {
  if (!(max_view_angle_deg > 0.0 && max_view_angle_deg <= 90.0)) {
    return MakeError("max_view_angle_deg must be in (0, 90]");
  }
  if (!(min_side_px >= 0.0)) return MakeError("min_side_px must be >= 0");
  if (!(border_margin_px >= 0.0)) return MakeError("border_margin_px must be >= 0");
  return Status::Ok();
}

std::map<TagId, QuadCorners> ProjectMappedTags(const CameraModel& camera, const Rigid3d& cam_from_world,
                                               const std::map<TagId, MapTag>& tags,
                                               const CornerPredictionOptions& options) {
  std::map<TagId, QuadCorners> predicted;
  const double min_cos = std::cos(options.max_view_angle_deg * M_PI / 180.0);
  for (const auto& [id, tag] : tags) {
    const TagCorners world = tag.CornersInWorld();
    std::array<Eigen::Vector3d, 4> cam;
    bool in_front = true;
    for (int k = 0; k < 4; ++k) {
      cam[k] = cam_from_world * world[k];
      in_front = in_front && cam[k].z() > 1e-3;
    }
    if (!in_front) continue;
    // The printed side faces the camera: corners run counter-clockwise seen
    // from the front, so (c1 - c0) x (c3 - c0) points out of the print, towards a viewer.
    const Eigen::Vector3d normal = (cam[1] - cam[0]).cross(cam[3] - cam[0]).normalized();
    const Eigen::Vector3d centre = 0.25 * (cam[0] + cam[1] + cam[2] + cam[3]);
    const double facing = -normal.dot(centre.normalized());
    if (!(facing >= min_cos)) continue;
    QuadCorners image;
    bool inside = true;
    double sides = 0.0;
    for (int k = 0; k < 4; ++k) {
      image[k] = camera.Project(cam[k]);
      const Eigen::Vector2d& c = image[k];
      inside = inside && c.allFinite() && c.x() >= options.border_margin_px && c.y() >= options.border_margin_px &&
               c.x() <= camera.width - 1 - options.border_margin_px &&
               c.y() <= camera.height - 1 - options.border_margin_px;
    }
    if (!inside) continue;
    for (int k = 0; k < 4; ++k) sides += (image[(k + 1) % 4] - image[k]).norm();
    if (!(0.25 * sides >= options.min_side_px)) continue;
    predicted[id] = image;
  }
  return predicted;
}

Rigid3d ExtrapolatePose(const Rigid3d& last, FrameId last_frame, const std::optional<Rigid3d>& before,
                        FrameId before_frame, FrameId frame, double max_steps) {
  if (!before || before_frame >= last_frame || frame <= last_frame) return last;
  const double steps = std::min(max_steps, static_cast<double>(frame - last_frame) /
                                               static_cast<double>(last_frame - before_frame));
  // The motion from `before` to `last` (in the camera frame), applied
  // `steps` times more: its rotation's angle and its translation scaled.
  const Rigid3d motion = last * before->Inverse();
  const Eigen::AngleAxisd turn(motion.rotation);
  const Eigen::Quaterniond rotation(Eigen::AngleAxisd(steps * turn.angle(), turn.axis()));
  return Rigid3d(rotation, steps * motion.translation) * last;
}

}  // namespace tagsfm
