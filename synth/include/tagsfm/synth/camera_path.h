#pragma once
// Camera poses around a scene: a smooth arc (video-like) or scattered photos.
#include <vector>

#include "tagsfm/core/rigid3d.h"
#include "tagsfm/synth/scene.h"
#include "tagsfm/synth/synth_options.h"

namespace tagsfm::synth {

struct CameraPath {
  std::vector<Rigid3d> cam_from_world;
  std::vector<std::int64_t> timestamps_ns;
};

// Every pose keeps all targets in front of the camera (z > 0.1 m); an option
// set for which that fails is an error.
Result<CameraPath> MakeCameraPath(const SynthOptions& options, const Scene& scene);

// cam_from_world of a camera at `centre` looking at `target`, world z up,
// rolled by `roll_rad` about the viewing direction.
Rigid3d LookAt(const Eigen::Vector3d& centre, const Eigen::Vector3d& target, double roll_rad);

}  // namespace tagsfm::synth
