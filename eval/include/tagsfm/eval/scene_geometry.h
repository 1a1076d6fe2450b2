#pragma once
// The scene's surfaces from a synthetic recording's ground_truth/scene.yaml
// (docs/synth.md): rectangles origin + a edge_u + b edge_v, a, b in [0, 1].
#include <filesystem>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "tagsfm/core/result.h"

namespace tagsfm::eval {

struct SurfaceRectangle {
  std::string name;
  Eigen::Vector3d origin, edge_u, edge_v;

  double DistanceTo(const Eigen::Vector3d& point) const;
};

Result<std::vector<SurfaceRectangle>> ReadSceneYaml(const std::filesystem::path& path);

// The rectangle nearest `point` (null when there are none) and, in
// `distance`, how far it is (infinity when there are none).
const SurfaceRectangle* NearestSurface(const std::vector<SurfaceRectangle>& surfaces, const Eigen::Vector3d& point,
                                       double* distance);

// Distance to the nearest rectangle (infinity when there are none).
double DistanceToSurfaces(const std::vector<SurfaceRectangle>& surfaces, const Eigen::Vector3d& point);

}  // namespace tagsfm::eval
