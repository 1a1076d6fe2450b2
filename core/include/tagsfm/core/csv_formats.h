#pragma once
// The shared CSV files of the interface contract:
//   poses.csv    frame,qw,qx,qy,qz,tx,ty,tz   (camera-from-world)
//   targets.csv  tag_id,corner,x,y,z          (metres, world frame)
#include <array>
#include <cstdint>
#include <filesystem>
#include <map>

#include <Eigen/Core>

#include "tagsfm/core/result.h"
#include "tagsfm/core/rigid3d.h"

namespace tagsfm {

using FrameId = std::int64_t;
using TagId = int;

// A tag's four corners in libapriltag's order (on the printed tag, seen from
// the front: bottom-left, bottom-right, top-right, top-left).
using TagCorners = std::array<Eigen::Vector3d, 4>;
using TargetCornerMap = std::map<TagId, TagCorners>;
using PoseMap = std::map<FrameId, Rigid3d>;  // frame -> cam_from_world

// A tag whose four corners are not all present is an error naming the tag.
Result<TargetCornerMap> ReadTargetsCsv(const std::filesystem::path& path);
Status WriteTargetsCsv(const std::filesystem::path& path, const TargetCornerMap& targets);

Result<PoseMap> ReadPosesCsv(const std::filesystem::path& path);
Status WritePosesCsv(const std::filesystem::path& path, const PoseMap& cam_from_world);

}  // namespace tagsfm
