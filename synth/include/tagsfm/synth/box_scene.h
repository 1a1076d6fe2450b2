#pragma once
// Synthetic tag correspondences for tests and benchmarks (recon's test
// scene): a true target map
// and true camera poses, with each visible tag's corners projected through
// the camera and perturbed by Gaussian pixel noise. No rendering: it checks
// the geometry, not the detector.
#include <cstdint>
#include <vector>

#include "tagsfm/core/camera_model.h"
#include "tagsfm/detect/tag_detection.h"

namespace tagsfm::synth {

struct SyntheticSceneOptions {
  int width = 1280, height = 720;
  double focal_px = 1000.0;
  // A box (the paper's armoire) with tags on its four sides and its top.
  double box_x = 1.0, box_y = 0.6, box_z = 1.2;
  int tags = 37;
  double tag_size_m = 0.06;
  // Cameras on a circle around the box, looking at its middle.
  int frames = 20;
  double min_distance_m = 1.5, max_distance_m = 3.0;
  double arc_deg = 300.0;       // how far around the box the cameras go
  double noise_px = 0.1;
  // false: each view jitters at random (a photo set); true: distance and
  // height vary slowly along the arc (a video).
  bool smooth_path = false;
  std::uint32_t seed = 1;        // layout and path
  std::uint32_t noise_seed = 0;  // the pixel noise; 0: derived from seed
};

struct SyntheticScene {
  CameraModel camera;
  TargetCornerMap targets;               // truth
  std::vector<Rigid3d> cam_from_world;   // truth, one per frame
  std::vector<DetectionSet> detections;  // noisy projections of the visible tags
  double largest_dimension_m = 0;
};

SyntheticScene MakeSyntheticBoxScene(const SyntheticSceneOptions& options);

// A tag is visible when it faces the camera (at least 15 degrees off its
// plane), lies in front of it and all four corners fall inside the image.
bool TagVisible(const CameraModel& camera, const Rigid3d& cam_from_world, const TagCorners& corners);

}  // namespace tagsfm::synth
