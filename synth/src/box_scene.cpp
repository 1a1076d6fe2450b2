#include "tagsfm/synth/box_scene.h"

#include <cmath>
#include <random>

#include "tagsfm/recon/tag_geometry.h"
#include "tagsfm/synth/camera_path.h"

namespace tagsfm::synth {

bool TagVisible(const CameraModel& camera, const Rigid3d& cam_from_world, const TagCorners& corners) {
  const Eigen::Vector3d centre = TagCenter(corners);
  const Eigen::Vector3d normal = (corners[1] - corners[0]).cross(corners[3] - corners[0]).normalized();
  const Eigen::Vector3d to_camera = (cam_from_world.Center() - centre).normalized();
  if (normal.dot(to_camera) < std::sin(15.0 * M_PI / 180.0)) return false;
  for (const auto& c : corners) {
    const Eigen::Vector3d p = cam_from_world * c;
    if (p.z() <= 0.05) return false;
    const Eigen::Vector2d px = camera.Project(p);
    if (px.x() < 2 || px.y() < 2 || px.x() > camera.width - 3 || px.y() > camera.height - 3) return false;
  }
  return true;
}

SyntheticScene MakeSyntheticBoxScene(const SyntheticSceneOptions& o) {
  SyntheticScene scene;
  scene.camera.width = o.width;
  scene.camera.height = o.height;
  scene.camera.fx = scene.camera.fy = o.focal_px;
  scene.camera.cx = (o.width - 1) / 2.0;
  scene.camera.cy = (o.height - 1) / 2.0;
  std::mt19937 rng(o.seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);

  // Tags on the faces: +x, -x, +y, -y sides and the top, spread at random
  // over each face (kept off the edges), upright on the sides.
  const double hx = o.box_x / 2, hy = o.box_y / 2;
  struct Face {
    Eigen::Vector3d origin, right, up;  // up: tag's +y; normal = right x up
    double width, height;
  };
  const std::vector<Face> faces = {
      {{hx, -hy, 0}, {0, 1, 0}, {0, 0, 1}, o.box_y, o.box_z},
      {{-hx, hy, 0}, {0, -1, 0}, {0, 0, 1}, o.box_y, o.box_z},
      {{hx, hy, 0}, {-1, 0, 0}, {0, 0, 1}, o.box_x, o.box_z},
      {{-hx, -hy, 0}, {1, 0, 0}, {0, 0, 1}, o.box_x, o.box_z},
      {{-hx, -hy, o.box_z}, {1, 0, 0}, {0, 1, 0}, o.box_x, o.box_y},
  };
  const double margin = o.tag_size_m;
  for (int id = 0; id < o.tags; ++id) {
    const Face& f = faces[static_cast<size_t>(id) % faces.size()];
    const double u = margin + unit(rng) * (f.width - 2 * margin);
    const double v = margin + unit(rng) * (f.height - 2 * margin);
    Eigen::Matrix3d rotation;
    rotation << f.right, f.up, f.right.cross(f.up);
    const Rigid3d world_from_tag(Eigen::Quaterniond(rotation), f.origin + u * f.right + v * f.up);
    scene.targets[id] = TagCornersInWorld(world_from_tag, o.tag_size_m);
  }
  scene.largest_dimension_m = std::sqrt(o.box_x * o.box_x + o.box_y * o.box_y + o.box_z * o.box_z);

  std::normal_distribution<double> noise(0.0, o.noise_px);
  std::mt19937 noise_rng(o.noise_seed != 0 ? o.noise_seed : o.seed * 7919u + 1u);
  const Eigen::Vector3d middle(0, 0, 0.5 * o.box_z);
  for (int i = 0; i < o.frames; ++i) {
    const double s = static_cast<double>(i) / std::max(1, o.frames - 1);
    const double a = o.arc_deg * M_PI / 180.0 * s + (o.smooth_path ? 0.0 : 0.3 * unit(rng));
    const double wave = 0.5 + 0.5 * std::sin(2 * M_PI * 3 * s);
    const double d = o.min_distance_m + (o.smooth_path ? wave : unit(rng)) * (o.max_distance_m - o.min_distance_m);
    const double height = o.box_z * (0.8 + 0.8 * (o.smooth_path ? 1 - wave : unit(rng)));
    const Eigen::Vector3d centre(d * std::cos(a), d * std::sin(a), height);
    const Eigen::Vector3d look =
        middle + (o.smooth_path ? Eigen::Vector3d::Zero()
                                : Eigen::Vector3d(0.1 * (unit(rng) - 0.5), 0.1 * (unit(rng) - 0.5), 0.0));
    const Rigid3d cam_from_world = LookAt(centre, look, 0.0);
    scene.cam_from_world.push_back(cam_from_world);
    DetectionSet set;
    set.frame = i;
    for (const auto& [id, corners] : scene.targets) {
      if (!TagVisible(scene.camera, cam_from_world, corners)) continue;
      TagDetection det;
      det.id = id;
      for (int k = 0; k < 4; ++k) {
        det.corners[k] = scene.camera.Project(cam_from_world * corners[k]) + Eigen::Vector2d(noise(noise_rng), noise(noise_rng));
      }
      det.decision_margin = 100;
      set.tags.push_back(det);
    }
    scene.detections.push_back(std::move(set));
  }
  return scene;
}

}  // namespace tagsfm::synth
