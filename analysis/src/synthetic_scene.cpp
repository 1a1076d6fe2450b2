#include "tagsfm/analysis/synthetic_scene.h"

#include <cmath>
#include <numbers>

#include <Eigen/Geometry>

#include "tagsfm/synth/camera_path.h"

namespace tagsfm::analysis {
namespace {

// A part of a hull: an axis-aligned box or a cylinder's side (caps are hidden
// against other parts or too small to matter).
struct Part {
  enum class Kind { kBox, kCylinder } kind;
  Eigen::Vector3d centre;
  Eigen::Vector3d half_extent;  // box: half sizes; cylinder: (radius, half length, axis index)
  double Area() const {
    if (kind == Kind::kBox) {
      const Eigen::Vector3d& h = half_extent;
      return 8.0 * (h.x() * h.y() + h.y() * h.z() + h.x() * h.z());
    }
    return 2.0 * std::numbers::pi * half_extent.x() * 2.0 * half_extent.y();
  }
};

SurfacePoint SampleBox(const Part& box, std::mt19937& rng) {
  const Eigen::Vector3d& h = box.half_extent;
  const double areas[3] = {h.y() * h.z(), h.x() * h.z(), h.x() * h.y()};  // faces normal to x, y, z
  std::discrete_distribution<int> pick_axis({areas[0], areas[1], areas[2]});
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  const int axis = pick_axis(rng);
  const double side = unit(rng) < 0 ? -1.0 : 1.0;
  Eigen::Vector3d local(unit(rng) * h.x(), unit(rng) * h.y(), unit(rng) * h.z());
  local[axis] = side * h[axis];
  SurfacePoint point;
  point.position = box.centre + local;
  point.normal = Eigen::Vector3d::Zero();
  point.normal[axis] = side;
  return point;
}

SurfacePoint SampleCylinder(const Part& cylinder, std::mt19937& rng) {
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  const double radius = cylinder.half_extent.x();
  const double half_length = cylinder.half_extent.y();
  const int axis = static_cast<int>(cylinder.half_extent.z());
  const double angle = std::numbers::pi * unit(rng);
  // The two axes across the cylinder, in order after `axis`.
  const int a = (axis + 1) % 3, b = (axis + 2) % 3;
  SurfacePoint point;
  point.normal = Eigen::Vector3d::Zero();
  point.normal[a] = std::cos(angle);
  point.normal[b] = std::sin(angle);
  point.position = cylinder.centre + radius * point.normal;
  point.position[axis] += half_length * unit(rng);
  return point;
}

std::vector<SurfacePoint> SampleParts(const std::vector<Part>& parts, int count, std::mt19937& rng) {
  std::vector<double> areas;
  for (const Part& part : parts) areas.push_back(part.Area());
  std::discrete_distribution<int> pick_part(areas.begin(), areas.end());
  std::vector<SurfacePoint> points;
  points.reserve(count);
  for (int i = 0; i < count; ++i) {
    const Part& part = parts[pick_part(rng)];
    points.push_back(part.kind == Part::Kind::kBox ? SampleBox(part, rng) : SampleCylinder(part, rng));
  }
  return points;
}

Part Box(Eigen::Vector3d centre, Eigen::Vector3d half) { return {Part::Kind::kBox, centre, half}; }
Part Cylinder(Eigen::Vector3d centre, double radius, double half_length, int axis) {
  return {Part::Kind::kCylinder, centre, Eigen::Vector3d(radius, half_length, axis)};
}

std::vector<Part> BradleyLikeParts() {
  return {Box({0, 0, 1.15}, {3.25, 1.6, 0.65}),     // hull
          Box({-0.3, 0, 2.25}, {1.1, 1.0, 0.45}),   // turret
          Cylinder({1.9, 0, 2.35}, 0.12, 1.3, 0),   // gun
          Cylinder({0, 1.45, 0.45}, 0.45, 2.9, 0),  // tracks
          Cylinder({0, -1.45, 0.45}, 0.45, 2.9, 0)};
}

std::vector<Part> MaxxproLikeParts() {
  std::vector<Part> parts = {Box({-0.4, 0, 1.95}, {2.6, 1.25, 0.95}),  // armoured body
                             Box({2.6, 0, 1.55}, {0.6, 1.1, 0.55})};   // engine hood
  for (double x : {-2.0, 2.0}) {
    for (double y : {-1.05, 1.05}) parts.push_back(Cylinder({x, y, 0.55}, 0.55, 0.2, 1));  // wheels
  }
  return parts;
}

// Cameras spread over a hemisphere (golden-angle spiral in azimuth, even in
// sin(elevation) between 5 and 60 degrees), at 9-14 units, each aimed at the
// object's centre with a little jitter, as a walk-around capture would be.
std::vector<Rigid3d> HemisphereCameras(int count, const Eigen::Vector3d& centre, std::mt19937& rng) {
  constexpr double kGoldenAngle = 2.399963229728653;
  const double min_sin = std::sin(5.0 * std::numbers::pi / 180.0);
  const double max_sin = std::sin(60.0 * std::numbers::pi / 180.0);
  std::uniform_real_distribution<double> radius_dist(9.0, 14.0);
  std::normal_distribution<double> aim_jitter(0.0, 0.3);
  std::vector<Rigid3d> cameras;
  cameras.reserve(count);
  for (int i = 0; i < count; ++i) {
    const double elevation = std::asin(min_sin + (max_sin - min_sin) * (i + 0.5) / count);
    const double azimuth = i * kGoldenAngle;
    const double radius = radius_dist(rng);
    const Eigen::Vector3d eye = centre + radius * Eigen::Vector3d(std::cos(elevation) * std::cos(azimuth),
                                                                  std::cos(elevation) * std::sin(azimuth),
                                                                  std::sin(elevation));
    const Eigen::Vector3d aim = centre + Eigen::Vector3d(aim_jitter(rng), aim_jitter(rng), aim_jitter(rng));
    cameras.push_back(synth::LookAt(eye, aim, 0.0));  // world z up, no roll
  }
  return cameras;
}

}  // namespace

CameraModel ExperimentCamera() {
  CameraModel camera;
  camera.width = 1280;
  camera.height = 960;
  camera.fx = camera.fy = 1000.0;
  camera.cx = (camera.width - 1) / 2.0;  // pixel centres at integers
  camera.cy = (camera.height - 1) / 2.0;
  return camera;
}

std::vector<SurfacePoint> BoxSurfacePoints(int count, double edge, std::mt19937& rng) {
  const double half = 0.5 * edge;
  return SampleParts({Box(Eigen::Vector3d::Zero(), Eigen::Vector3d(half, half, half))}, count, rng);
}

SyntheticObject MakeVehicle(VehicleKind kind, std::uint32_t seed) {
  std::mt19937 rng(seed);
  SyntheticObject object;
  const bool bradley = kind == VehicleKind::kBradleyLike;
  object.name = bradley ? "bradley-like" : "maxxpro-like";
  // Dense enough that every camera sees well over the 1000 points the sweeps draw.
  object.surface = SampleParts(bradley ? BradleyLikeParts() : MaxxproLikeParts(), 20000, rng);
  object.centre = bradley ? Eigen::Vector3d(0, 0, 1.35) : Eigen::Vector3d(0.2, 0, 1.45);
  object.cameras = HemisphereCameras(bradley ? 1234 : 278, object.centre, rng);
  return object;
}

Eigen::Vector2d ProjectToPixel(const CameraModel& camera, const Eigen::Vector3d& point_in_cam) {
  return {camera.fx * point_in_cam.x() / point_in_cam.z() + camera.cx,
          camera.fy * point_in_cam.y() / point_in_cam.z() + camera.cy};
}

std::vector<int> VisiblePoints(const std::vector<SurfacePoint>& surface, const Rigid3d& cam_from_world,
                               const CameraModel& camera) {
  const Eigen::Vector3d centre = cam_from_world.Center();
  const Eigen::Matrix3d rotation = cam_from_world.RotationMatrix();
  std::vector<int> visible;
  for (size_t i = 0; i < surface.size(); ++i) {
    if (surface[i].normal.dot(centre - surface[i].position) <= 0) continue;  // faces away
    const Eigen::Vector3d in_cam = rotation * surface[i].position + cam_from_world.translation;
    if (in_cam.z() < 0.1) continue;
    const Eigen::Vector2d px = ProjectToPixel(camera, in_cam);
    if (px.x() < 0 || px.y() < 0 || px.x() > camera.width - 1 || px.y() > camera.height - 1) continue;
    visible.push_back(static_cast<int>(i));
  }
  return visible;
}

}  // namespace tagsfm::analysis
