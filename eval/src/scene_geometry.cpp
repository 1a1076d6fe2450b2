#include "tagsfm/eval/scene_geometry.h"

#include <algorithm>
#include <limits>

#include <yaml-cpp/yaml.h>

#include "tagsfm/capture/yaml_file.h"

namespace tagsfm::eval {

double SurfaceRectangle::DistanceTo(const Eigen::Vector3d& point) const {
  const Eigen::Vector3d d = point - origin;
  const double a = std::clamp(d.dot(edge_u) / edge_u.squaredNorm(), 0.0, 1.0);
  const double b = std::clamp(d.dot(edge_v) / edge_v.squaredNorm(), 0.0, 1.0);
  return (origin + a * edge_u + b * edge_v - point).norm();
}

const SurfaceRectangle* NearestSurface(const std::vector<SurfaceRectangle>& surfaces, const Eigen::Vector3d& point,
                                       double* distance) {
  const SurfaceRectangle* nearest = nullptr;
  *distance = std::numeric_limits<double>::infinity();
  for (const SurfaceRectangle& s : surfaces) {
    const double d = s.DistanceTo(point);
    if (d < *distance) {
      *distance = d;
      nearest = &s;
    }
  }
  return nearest;
}

double DistanceToSurfaces(const std::vector<SurfaceRectangle>& surfaces, const Eigen::Vector3d& point) {
  double distance = 0.0;
  NearestSurface(surfaces, point, &distance);
  return distance;
}

Result<std::vector<SurfaceRectangle>> ReadSceneYaml(const std::filesystem::path& path) {
  const std::string file = path.string();
  Result<YAML::Node> root = LoadYamlFile(file);
  if (!root) return root.error();
  const YAML::Node faces = (*root)["faces"];
  if (!faces || !faces.IsSequence()) return MakeError(file + ": faces is missing or not a list");
  std::vector<SurfaceRectangle> surfaces;
  for (size_t i = 0; i < faces.size(); ++i) {
    const std::string where = file + ": faces[" + std::to_string(i) + "].";
    SurfaceRectangle s;
    try {
      s.name = faces[i]["name"] ? faces[i]["name"].as<std::string>() : "face" + std::to_string(i);
      Eigen::Vector3d* fields[] = {&s.origin, &s.edge_u, &s.edge_v};
      const char* names[] = {"origin", "edge_u", "edge_v"};
      for (int f = 0; f < 3; ++f) {
        const YAML::Node v = faces[i][names[f]];
        if (!v || !v.IsSequence() || v.size() != 3) return MakeError(where + names[f] + " must be a list of 3 numbers");
        *fields[f] = Eigen::Vector3d(v[0].as<double>(), v[1].as<double>(), v[2].as<double>());
      }
    } catch (const YAML::Exception&) {
      return MakeError(where + " has a value of the wrong type");
    }
    if (!(s.edge_u.norm() > 0) || !(s.edge_v.norm() > 0)) return MakeError(where + "edge_u/edge_v must be non-zero");
    surfaces.push_back(s);
  }
  return surfaces;
}

}  // namespace tagsfm::eval
