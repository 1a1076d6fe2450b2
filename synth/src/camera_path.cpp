// Camera paths: an arc around the scene sampled at 30 fps, or photo-like
// scattered views; each looks at the scene centre with some jitter (the
// room: from inside, at its walls).
#include "tagsfm/synth/camera_path.h"

#include <cmath>

#include <opencv2/core.hpp>

namespace tagsfm::synth {
namespace {

using Eigen::Vector3d;

constexpr double kDeg = M_PI / 180;
constexpr std::int64_t kVideoFps = 30;
constexpr std::int64_t kPhotoGapNs = 2'000'000'000;

// The span of viewing directions each scene is seen from: azimuth about the
// world z axis (0 = from the front, -y), elevation above the horizontal.
struct ViewRange {
  double max_azimuth, min_elevation, max_elevation;
};

ViewRange RangeOf(const Scene& scene, const SynthOptions& options) {
  ViewRange range = scene.name == "box" ? ViewRange{70 * kDeg, 5 * kDeg, 35 * kDeg} : ViewRange{35 * kDeg, -10 * kDeg, 15 * kDeg};
  if (options.max_azimuth_deg > 0) range.max_azimuth = options.max_azimuth_deg * kDeg;
  return range;
}

Vector3d Direction(double azimuth, double elevation) {
  return {std::sin(azimuth) * std::cos(elevation), -std::cos(azimuth) * std::cos(elevation), std::sin(elevation)};
}

bool AllTargetsInFront(const Rigid3d& cam_from_world, const TargetCornerMap& targets) {
  for (const auto& [id, corners] : targets) {
    for (const Eigen::Vector3d& corner : corners) {
      if ((cam_from_world * corner).z() < 0.1) return false;
    }
  }
  return true;
}

// Smooth pseudo-random wiggle in [-1, 1] along the path parameter s in [0, 1].
struct Wiggle {
  double f1, f2, p1, p2;
  explicit Wiggle(cv::RNG& rng)
      : f1(rng.uniform(0.7, 1.6)), f2(rng.uniform(1.7, 3.1)), p1(rng.uniform(0.0, 2 * M_PI)), p2(rng.uniform(0.0, 2 * M_PI)) {}
  double operator()(double s) const {
    return 0.65 * std::sin(2 * M_PI * f1 * s + p1) + 0.35 * std::sin(2 * M_PI * f2 * s + p2);
  }
};

// The room is seen from inside: the camera walks round a 0.5 m circle about
// the room's centre facing the walls and turns 400 degrees, so that the
// loop closes on the walls it began with (orbit); or stands anywhere within
// 0.8 m of the centre facing any way (photos). Aimed at a wall 2 m ahead.
CameraPath RoomPath(const SynthOptions& options, const Scene& scene, cv::RNG& rng) {
  CameraPath path;
  constexpr double kTurn = 400 * kDeg;
  if (options.path == "orbit") {
    const Wiggle radius(rng), height(rng), heading(rng), elevation(rng), roll(rng);
    for (int i = 0; i < options.frames; ++i) {
      const double s = options.frames > 1 ? static_cast<double>(i) / (options.frames - 1) : 0.5;
      const double walk = s * kTurn;
      const Vector3d centre = scene.look_at + (0.5 + 0.1 * radius(s)) * Vector3d(std::cos(walk), std::sin(walk), 0) +
                              Vector3d(0, 0, 0.1 * height(s));
      const double yaw = walk + 10 * kDeg * heading(s), pitch = (2.5 + 7.5 * elevation(s)) * kDeg;
      const Vector3d aim = centre + 2.0 * Vector3d(std::cos(yaw) * std::cos(pitch), std::sin(yaw) * std::cos(pitch), std::sin(pitch));
      path.cam_from_world.push_back(LookAt(centre, aim, 3 * kDeg * roll(s)));
      path.timestamps_ns.push_back(i * std::int64_t{1'000'000'000} / kVideoFps);
    }
    return path;
  }
  for (int i = 0; i < options.frames; ++i) {
    const double r = 0.8 * std::sqrt(rng.uniform(0.0, 1.0)), at = rng.uniform(0.0, 2 * M_PI);
    const Vector3d centre = scene.look_at + Vector3d(r * std::cos(at), r * std::sin(at), rng.uniform(-0.2, 0.2));
    const double yaw = rng.uniform(0.0, 2 * M_PI), pitch = rng.uniform(-5.0, 15.0) * kDeg;
    const Vector3d aim = centre + 2.0 * Vector3d(std::cos(yaw) * std::cos(pitch), std::sin(yaw) * std::cos(pitch), std::sin(pitch));
    path.cam_from_world.push_back(LookAt(centre, aim, rng.uniform(-8.0, 8.0) * kDeg));
    path.timestamps_ns.push_back(i * kPhotoGapNs);
  }
  return path;
}

}  // namespace

Rigid3d LookAt(const Vector3d& centre, const Vector3d& target, double roll_rad) {
  const Vector3d forward = (target - centre).normalized();
  Vector3d right = forward.cross(Vector3d::UnitZ());
  if (right.norm() < 1e-9) right = Vector3d::UnitX();  // looking straight down or up
  right.normalize();
  const Vector3d down = forward.cross(right);
  const double c = std::cos(roll_rad), s = std::sin(roll_rad);
  Eigen::Matrix3d world_from_cam;
  world_from_cam.col(0) = c * right + s * down;
  world_from_cam.col(1) = -s * right + c * down;
  world_from_cam.col(2) = forward;
  const Eigen::Matrix3d cam_from_world = world_from_cam.transpose();
  return Rigid3d(Eigen::Quaterniond(cam_from_world), -(cam_from_world * centre));
}

Result<CameraPath> MakeCameraPath(const SynthOptions& options, const Scene& scene) {
  if (Status s = options.Check(); !s) return s.error();
  const ViewRange range = RangeOf(scene, options);
  const TargetCornerMap targets = SceneTargets(scene);
  cv::RNG rng(options.seed * 6364136223846793005ULL + 99);
  if (scene.name == "room") return RoomPath(options, scene, rng);  // targets all round: some always behind
  CameraPath path;
  const double mid_distance = 0.5 * (options.min_distance + options.max_distance);
  const double half_distance = 0.5 * (options.max_distance - options.min_distance);
  const double mid_elevation = 0.5 * (range.min_elevation + range.max_elevation);
  const double half_elevation = 0.5 * (range.max_elevation - range.min_elevation);
  if (options.path == "orbit") {
    const Wiggle distance(rng), elevation(rng), aim_x(rng), aim_y(rng), aim_z(rng), roll(rng);
    for (int i = 0; i < options.frames; ++i) {
      const double s = options.frames > 1 ? static_cast<double>(i) / (options.frames - 1) : 0.5;
      const double azimuth = (2 * s - 1) * range.max_azimuth;
      const Vector3d centre = scene.look_at + (mid_distance + half_distance * distance(s)) *
                                                  Direction(azimuth, mid_elevation + half_elevation * elevation(s));
      const Vector3d aim = scene.look_at + 0.08 * Vector3d(aim_x(s), aim_y(s), aim_z(s));
      path.cam_from_world.push_back(LookAt(centre, aim, 3 * kDeg * roll(s)));
      path.timestamps_ns.push_back(i * std::int64_t{1'000'000'000} / kVideoFps);
    }
  } else {
    for (int i = 0; i < options.frames; ++i) {
      const double azimuth = rng.uniform(-range.max_azimuth, range.max_azimuth);
      const double elevation = rng.uniform(range.min_elevation, range.max_elevation);
      const double distance = rng.uniform(options.min_distance, options.max_distance);
      const Vector3d aim = scene.look_at + Vector3d(rng.uniform(-0.15, 0.15), rng.uniform(-0.15, 0.15),
                                                    rng.uniform(-0.15, 0.15));
      const double roll = rng.uniform(-8.0, 8.0) * kDeg;
      path.cam_from_world.push_back(LookAt(scene.look_at + distance * Direction(azimuth, elevation), aim, roll));
      path.timestamps_ns.push_back(i * kPhotoGapNs);
    }
  }
  for (size_t i = 0; i < path.cam_from_world.size(); ++i) {
    if (!AllTargetsInFront(path.cam_from_world[i], targets)) {
      return MakeError("--distance: frame " + std::to_string(i) +
                       " would have a target behind or too close to the camera; increase the distance");
    }
  }
  return path;
}

}  // namespace tagsfm::synth
