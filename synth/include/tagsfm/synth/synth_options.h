#pragma once
// What `tagsfm synth` renders: the scene, the camera and its path, the sensor.
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "tagsfm/core/camera_model.h"
#include "tagsfm/core/result.h"

namespace tagsfm::synth {

struct SynthOptions {
  std::string scene = "box";   // box | wall | room
  std::string path = "orbit";  // orbit (video-like, 30 fps) | photos (a few scattered views)
  int frames = 30;
  int width = 1280;
  int height = 720;
  double fx = 0.0;  // 0: 0.78125 * width, a 65 degree horizontal field of view
  double fy = 0.0;  // 0: same as fx
  std::vector<double> distortion;  // OpenCV's k1 k2 p1 p2 [k3]; empty: none
  double noise = 2.0;       // std of Gaussian image noise, grey levels
  double blur = 0.7;        // std of the Gaussian optical blur, pixels (0: none)
  double brightness = 1.0;  // scene illumination factor (the paper's lighting test)
  std::uint64_t seed = 1;   // textures, tag layout, path jitter, noise
  std::string family = "tag36h11";
  double tag_size = 0.06;   // edge of the tag's detector quad (black square for tag36h11), metres
  // White modules round the detector's square (the black square of tag36h11),
  // the surface's texture beyond: 1 = libapriltag's official image printed
  // edge to edge (its own outer ring), 2 = one module of paper more (what
  // synth drew before this option; the bundled recordings/).
  double tag_margin = 1.0;
  // The printer's scale: tags are drawn (and their true corners written)
  // at tag_size * print_scale while recording.yaml says tag_size, as a
  // printer that prints 0.5 % too large does (1.005).
  double print_scale = 1.0;
  // Scale bars written into recording.yaml: pairs of tag ids, centre to
  // centre, with the true (printed) distance and scale_bar_sigma_m.
  std::vector<std::pair<int, int>> scale_bars;
  double scale_bar_sigma_m = 1e-5;
  double min_distance = 1.5;  // camera to the scene centre, metres
  double max_distance = 3.0;
  double max_azimuth_deg = 0.0;  // views from +-this about the scene's front; 0: 70 (box), 35 (wall)
  int samples = 4;          // antialiasing: samples x samples per pixel
  int threads = 2;
  bool with_map = false;    // also write the true targets.csv and name it in recording.yaml

  // Names the first wrong field, e.g. "--frames must be >= 1 (got 0)".
  Status Check() const;
  // The camera these options describe (fx defaulted, principal point centred).
  CameraModel Camera() const;
};

}  // namespace tagsfm::synth
