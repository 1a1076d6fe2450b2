#pragma once
// Ray-casting a Scene through a CameraModel, with box-filter antialiasing,
// then the sensor: blur, brightness, noise, 8-bit quantisation.
#include <cstdint>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "tagsfm/core/camera_model.h"
#include "tagsfm/core/rigid3d.h"
#include "tagsfm/synth/scene.h"

namespace tagsfm::synth {

class SceneRenderer {
 public:
  // Precomputes the undistorted ray of every pixel corner (intrinsics are
  // fixed for a recording). `samples` x `samples` stratified, jittered
  // sub-pixel samples average over each pixel's square footprint.
  static Result<SceneRenderer> Create(const CameraModel& camera, const Scene* scene, int samples, int threads);

  // Scene radiance (albedo x face shade), one float per pixel, in [0, 1].
  cv::Mat1f Render(const Rigid3d& cam_from_world) const;

  const CameraModel& camera() const { return camera_; }

 private:
  void RenderRows(const Rigid3d& cam_from_world, int first_row, int row_step, cv::Mat1f* out) const;

  CameraModel camera_;
  const Scene* scene_ = nullptr;
  int samples_ = 4;
  int threads_ = 2;
  // Normalised image coordinates (x/z, y/z) at the pixel corners
  // (u - 0.5, v - 0.5), (width + 1) x (height + 1), row-major.
  std::vector<Eigen::Vector2d> corner_rays_;
};

struct SensorOptions {
  double blur = 0.7;        // Gaussian std, pixels
  double brightness = 1.0;  // multiplies the radiance
  double noise = 2.0;       // Gaussian std, grey levels
};

// radiance in [0, 1] -> 8-bit grey: blur, x brightness x 255, + noise, round, clip.
cv::Mat ApplySensorModel(const cv::Mat1f& radiance, const SensorOptions& options, std::uint64_t noise_seed);

}  // namespace tagsfm::synth
