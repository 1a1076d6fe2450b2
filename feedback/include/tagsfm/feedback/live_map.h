#pragma once
// What the dashboard's top view draws: where the targets seen so far are in
// the world, where the camera has been and where it looks now. Positions come
// from each registered frame's pose and the tags' own poses in that frame, so
// the map grows as the operator walks, without waiting for an adjustment.
#include <map>
#include <optional>
#include <vector>

#include "tagsfm/feedback/coverage.h"
#include "tagsfm/recon/reconstructor.h"

namespace tagsfm {

// Bounds what the status carries (and copies each frame) on long captures.
inline constexpr size_t kMaxCameraPathPoints = 512;

struct MapTarget {
  TagId id = -1;
  Eigen::Vector3d centre_in_world = Eigen::Vector3d::Zero();  // mean over the registered frames that saw it
};

struct LiveMap {
  std::vector<MapTarget> targets;                        // by id
  std::optional<Eigen::Vector3d> camera_in_world;        // this frame's camera centre, when registered
  std::optional<Eigen::Vector3d> camera_axis_in_world;   // unit optical axis, when registered
  std::vector<Eigen::Vector3d> camera_path;              // registered centres, evenly thinned to kMaxCameraPathPoints
  // The top view's axes (unit, orthogonal, both perpendicular to "up": the
  // mean of the camera's up directions so far, as an operator holds it).
  Eigen::Vector3d top_x = Eigen::Vector3d::UnitX();
  Eigen::Vector3d top_y = Eigen::Vector3d::UnitY();
};

class LiveMapTracker {
 public:
  // `views`: the frame's tags (ComputeTagViews), in the camera frame.
  void Add(const FrameReport& report, const std::vector<TagSighting>& views);
  const LiveMap& map() const { return map_; }

 private:
  void AddToPath(const Eigen::Vector3d& centre);
  void UpdateTopAxes(const Rigid3d& cam_from_world);

  LiveMap map_;
  std::map<TagId, std::pair<Eigen::Vector3d, int>> sums_;  // centre sum and count per target
  Eigen::Vector3d up_sum_ = Eigen::Vector3d::Zero();
  std::optional<Eigen::Vector3d> first_right_;  // the first camera's right: keeps the view from spinning
  size_t path_stride_ = 1;
  size_t registered_ = 0;
};

}  // namespace tagsfm
