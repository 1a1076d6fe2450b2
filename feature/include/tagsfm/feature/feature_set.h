#pragma once
// One keyframe's features with their track ids: the input of
// TriangulateFeatureTracks (feature_triangulation.h). (Kept from the
// consecutive-keyframe tracker that the feature map replaced.)
#include <array>
#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "tagsfm/core/csv_formats.h"

namespace tagsfm {

using TrackId = std::int64_t;

struct FeatureObservation {
  TrackId track = -1;
  Eigen::Vector2d pixel = Eigen::Vector2d::Zero();  // OpenCV convention, distorted coordinates
  std::array<std::uint8_t, 3> rgb{0, 0, 0};
};

struct FeatureSet {
  FrameId frame = 0;
  std::vector<FeatureObservation> features;
  int continued = 0;  // features that continue a track of the previous keyframe
};

}  // namespace tagsfm
