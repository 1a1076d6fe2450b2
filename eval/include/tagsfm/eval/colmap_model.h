#pragma once
// Reading a COLMAP text model (cameras.txt, images.txt, points3D.txt), as
// COLMAP's model_converter --output_type TXT writes it, so that a COLMAP
// reconstruction can be scored against a recording's ground truth like a
// tagsfm result. images.txt poses are world-to-camera (QW QX QY QZ TX TY
// TZ), the convention of our poses.csv.
#include <array>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "tagsfm/capture/recording.h"
#include "tagsfm/core/csv_formats.h"
#include "tagsfm/core/result.h"
#include "tagsfm/core/rigid3d.h"

namespace tagsfm::eval {

struct ColmapCamera {
  long long id = 0;
  std::string model;  // PINHOLE, OPENCV, SIMPLE_RADIAL, ...
  int width = 0, height = 0;
  std::vector<double> params;
};

struct ColmapImage {
  long long id = 0;
  long long camera_id = 0;
  std::string name;  // relative to the image_path COLMAP was given
  Rigid3d cam_from_world;
  int points2d = 0;           // keypoints listed on the image's second line
  int observed_points2d = 0;  // of those, the ones with a 3D point
};

struct ColmapPoint {
  long long id = 0;
  Eigen::Vector3d xyz = Eigen::Vector3d::Zero();
  std::array<int, 3> rgb{};
  double error_px = 0;  // COLMAP's ERROR: the mean reprojection error over the track
  int track_length = 0;
};

struct ColmapModel {
  std::map<long long, ColmapCamera> cameras;
  std::map<std::string, ColmapImage> images_by_name;
  std::vector<ColmapPoint> points;
};

// True when `dir` holds images.txt and points3D.txt.
bool IsColmapTextModel(const std::filesystem::path& dir);

// Each reader fails with one line naming the file and line at fault
// (malformed numbers, missing fields, a file cut short, duplicate ids).
Result<std::map<long long, ColmapCamera>> ReadColmapCamerasTxt(const std::filesystem::path& path);
Result<std::map<std::string, ColmapImage>> ReadColmapImagesTxt(const std::filesystem::path& path);
Result<std::vector<ColmapPoint>> ReadColmapPoints3DTxt(const std::filesystem::path& path);

// All three; an image naming a camera cameras.txt lacks is an error.
Result<ColmapModel> ReadColmapTextModel(const std::filesystem::path& dir);

// The model's poses by the recording's frame ids: an image named as
// frames.csv names the file (relative to REC), or by its bare file name
// when that is unique in the recording (COLMAP run on REC/frames/).
struct ColmapFramePoses {
  PoseMap cam_from_world;
  std::vector<std::string> unmatched_images;  // names no frame has
};
ColmapFramePoses MatchImagesToFrames(const ColmapModel& model, const std::vector<FrameEntry>& frames,
                                     const std::filesystem::path& rec_dir);

}  // namespace tagsfm::eval
