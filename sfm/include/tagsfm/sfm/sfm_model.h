#pragma once
// The state of an incremental reconstruction as plain values: images with
// their features (undistorted) and poses, 3D points with their tracks.
#include <array>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "tagsfm/core/csv_formats.h"
#include "tagsfm/core/rigid3d.h"

namespace tagsfm::sfm {

using ImageIdx = int;  // index into SfmModel::images
using PointIdx = int;  // index into SfmModel::points; -1: none

struct SfmImage {
  FrameId frame = 0;
  std::vector<Eigen::Vector2d> pixels;      // as detected (distorted)
  std::vector<Eigen::Vector2d> normalized;  // undistorted x/z, y/z
  std::vector<PointIdx> point_of_feature;   // -1 where the feature has no 3D point
  bool registered = false;
  Rigid3d cam_from_world;
  std::string reason;  // why unregistered
};

struct Observation {
  ImageIdx image = -1;
  int feature = -1;
};

struct SfmPoint {
  Eigen::Vector3d xyz = Eigen::Vector3d::Zero();
  std::array<std::uint8_t, 3> rgb{0, 0, 0};
  std::vector<Observation> track;
  bool deleted = false;
};

struct SfmModel {
  std::vector<SfmImage> images;
  std::vector<SfmPoint> points;
  // Gauge: the first image of the initial pair is the world frame, the
  // second's distance from it is 1 (the initial baseline).
  ImageIdx gauge_origin = -1, gauge_scale = -1;

  int RegisteredImages() const;
  int LivePoints() const;
  PointIdx AddPoint(const Eigen::Vector3d& xyz, const std::array<std::uint8_t, 3>& rgb, std::vector<Observation> track);
  void AddObservation(PointIdx point, Observation obs);
  void DeletePoint(PointIdx point);
  void RemoveObservation(PointIdx point, size_t track_index);
};

}  // namespace tagsfm::sfm
