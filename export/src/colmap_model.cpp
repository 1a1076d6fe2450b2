// colmap/{cameras,images,points3D}.txt: COLMAP's text model of the result,
// the target corners and feature points as its 3D points.
#include <iomanip>
#include <map>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "corner_stats.h"
#include "tagsfm/core/file_util.h"
#include "tagsfm/core/number_text.h"
#include "tagsfm/export/result_writer.h"

namespace tagsfm {
namespace {

std::string FrameName(const RunStats& stats, FrameId frame) {
  auto it = stats.image_names.find(frame);
  if (it != stats.image_names.end()) return it->second;
  std::ostringstream name;
  name << "frame_" << std::setw(6) << std::setfill('0') << frame;
  return name.str();
}

// COLMAP's point id of a tag corner (ids start at 1).
long long CornerPointId(TagId id, int corner) { return 4LL * id + corner + 1; }

// COLMAP's 3D point id -> its views as (image id, index among the image's 2D points).
using ColmapTracks = std::map<long long, std::vector<std::pair<int, int>>>;

// cameras.txt: one camera, the model that holds the lens's coefficients.
// COLMAP puts pixel centres at .5, tagsfm at integers: shift by half a pixel.
std::string CamerasText(const CameraModel& c) {
  std::ostringstream cameras;
  cameras << std::setprecision(17) << "# Camera list with one line of data per camera:\n"
          << "#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n# Number of cameras: 1\n";
  const auto coef = [&c](size_t i) { return i < c.distortion.size() ? c.distortion[i] : 0.0; };
  if (c.kind == CameraModel::Kind::kFisheye) {
    cameras << "1 OPENCV_FISHEYE " << c.width << " " << c.height << " " << c.fx << " " << c.fy << " " << c.cx + 0.5
            << " " << c.cy + 0.5 << " " << coef(0) << " " << coef(1) << " " << coef(2) << " " << coef(3) << "\n";
  } else if (!c.HasDistortion()) {
    cameras << "1 PINHOLE " << c.width << " " << c.height << " " << c.fx << " " << c.fy << " " << c.cx + 0.5 << " "
            << c.cy + 0.5 << "\n";
  } else if (c.distortion.size() <= 4 || (coef(4) == 0 && c.distortion.size() <= 5)) {
    cameras << "1 OPENCV " << c.width << " " << c.height << " " << c.fx << " " << c.fy << " " << c.cx + 0.5 << " "
            << c.cy + 0.5 << " " << coef(0) << " " << coef(1) << " " << coef(2) << " " << coef(3) << "\n";
  } else {
    cameras << "1 FULL_OPENCV " << c.width << " " << c.height << " " << c.fx << " " << c.fy << " " << c.cx + 0.5
            << " " << c.cy + 0.5;
    for (size_t i = 0; i < 8; ++i) cameras << " " << coef(i);
    cameras << "\n";
  }
  return cameras.str();
}

// images.txt: one image per registered frame, its 2D points the tag corners
// (mapped ones with their point id) and then its feature observations;
// `tracks` gets every 3D point's views.
std::string ImagesText(const ReconstructionResult& result, const RunStats& stats, ColmapTracks* tracks) {
  std::ostringstream images;
  images << "# Image list with two lines of data per image:\n"
         << "#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME\n#   POINTS2D[] as (X, Y, POINT3D_ID)\n";
  // Feature observations by frame: (pixel, point id).
  std::map<FrameId, std::vector<std::pair<Eigen::Vector2d, long long>>> feature_views;
  for (size_t i = 0; i < result.feature_points.size(); ++i) {
    for (const auto& [frame, pixel] : result.feature_points[i].observations) {
      feature_views[frame].emplace_back(pixel, kFirstFeaturePointId + static_cast<long long>(i));
    }
  }
  int image_id = 0;
  for (const auto& f : result.frames) {
    if (!f.registered) continue;
    ++image_id;
    const Rigid3d pose = f.cam_from_world.ToRigid();
    images << image_id << " " << ExactText(pose.rotation.w()) << " " << ExactText(pose.rotation.x()) << " "
           << ExactText(pose.rotation.y()) << " " << ExactText(pose.rotation.z()) << " " << ExactText(pose.translation.x())
           << " " << ExactText(pose.translation.y()) << " " << ExactText(pose.translation.z()) << " 1 "
           << FrameName(stats, f.frame) << "\n";
    int index = 0;
    bool first = true;
    for (const auto& obs : f.tags) {
      const bool mapped = result.tags.count(obs.id) > 0;
      for (int k = 0; k < 4; ++k) {
        const long long point_id = mapped ? CornerPointId(obs.id, k) : -1;
        images << (first ? "" : " ") << ExactText(obs.pixels[k].x() + 0.5) << " " << ExactText(obs.pixels[k].y() + 0.5)
               << " " << point_id;
        first = false;
        if (mapped) (*tracks)[point_id].emplace_back(image_id, index);
        ++index;
      }
    }
    if (auto it = feature_views.find(f.frame); it != feature_views.end()) {
      for (const auto& [pixel, point_id] : it->second) {
        images << (first ? "" : " ") << ExactText(pixel.x() + 0.5) << " " << ExactText(pixel.y() + 0.5) << " " << point_id;
        first = false;
        (*tracks)[point_id].emplace_back(image_id, index++);
      }
    }
    images << "\n";
  }
  return images.str();
}

// points3D.txt: the tag corners (blue: a known map's, orange: learned; error:
// their reprojection RMS), then the feature points, each with its views.
std::string PointsText(const ReconstructionResult& result, ColmapTracks& tracks) {
  const auto corner_stats = ComputeCornerStats(result);
  std::ostringstream points;
  points << "# 3D point list with one line of data per point:\n"
         << "#   POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[] as (IMAGE_ID, POINT2D_IDX)\n";
  for (const auto& [id, tag] : result.tags) {
    const TagCorners corners = tag.CornersInWorld();
    for (int k = 0; k < 4; ++k) {
      const long long point_id = CornerPointId(id, k);
      auto it = corner_stats.find({id, k});
      points << point_id << " " << ExactText(corners[k].x()) << " " << ExactText(corners[k].y()) << " "
             << ExactText(corners[k].z()) << " " << (tag.known ? "40 90 255 " : "255 140 0 ")
             << ExactText(it == corner_stats.end() ? 0.0 : it->second.rms_px);
      for (const auto& [img, idx] : tracks[point_id]) points << " " << img << " " << idx;
      points << "\n";
    }
  }
  for (size_t i = 0; i < result.feature_points.size(); ++i) {
    const FeaturePoint& p = result.feature_points[i];
    const long long point_id = kFirstFeaturePointId + static_cast<long long>(i);
    points << point_id << " " << ExactText(p.position.x()) << " " << ExactText(p.position.y()) << " "
           << ExactText(p.position.z()) << " " << int{p.rgb[0]} << " " << int{p.rgb[1]} << " " << int{p.rgb[2]} << " "
           << ExactText(p.reprojection_rms_px);
    for (const auto& [img, idx] : tracks[point_id]) points << " " << img << " " << idx;
    points << "\n";
  }
  return points.str();
}

}  // namespace

Status WriteColmapModel(const std::filesystem::path& dir, const ReconstructionResult& result, const RunStats& stats) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) return MakeError(dir.string() + ": cannot create (" + ec.message() + ")");
  ColmapTracks tracks;
  const std::string images = ImagesText(result, stats, &tracks);
  if (Status s = WriteFileAtomically(dir / "cameras.txt", CamerasText(result.camera)); !s) return s;
  if (Status s = WriteFileAtomically(dir / "images.txt", images); !s) return s;
  return WriteFileAtomically(dir / "points3D.txt", PointsText(result, tracks));
}

}  // namespace tagsfm
