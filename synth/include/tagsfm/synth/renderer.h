#pragma once
// Ray-casting a Scene through a CameraModel: the lens blur, then each
// pixel's square footprint (box filter); then the sensor: brightness, noise,
// 8-bit quantisation.
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

  // The light each pixel collects, in [0, 1] (albedo x face shade): the
  // scene's radiance blurred by the lens (a Gaussian point-spread function of
  // std `blur_px` pixels), then integrated over the pixel's square, in that
  // order, as in a camera. Blurring the integrated pixels instead is not an
  // optics blur below ~1 px (OpenCV's sampled kernel at sigma 0.5 is
  // [0.11, 0.79, 0.11]) and moved rendered tag corners ~0.002 px inward
  // (docs/detection.md, docs/synth.md).
  cv::Mat1f Render(const Rigid3d& cam_from_world, double blur_px = 0.0) const;

  const CameraModel& camera() const { return camera_; }

 private:
  // Rows first_row, first_row + row_step, ... of the image; with
  // `per_sample` each sample's value goes to its own cell of a
  // samples-times-finer `out`, else each pixel gets the mean of its samples.
  void RenderRows(const Rigid3d& cam_from_world, int first_row, int row_step, bool per_sample, cv::Mat1f* out) const;

  CameraModel camera_;
  const Scene* scene_ = nullptr;
  int samples_ = 4;
  int threads_ = 2;
  // Normalised image coordinates (x/z, y/z) at the pixel corners
  // (u - 0.5, v - 0.5), (width + 1) x (height + 1), row-major.
  std::vector<Eigen::Vector2d> corner_rays_;
};

struct SensorOptions {
  double brightness = 1.0;  // multiplies the collected light
  double noise = 2.0;       // Gaussian std, grey levels
};

// collected light in [0, 1] -> 8-bit grey: x brightness x 255, + noise, round, clip.
cv::Mat ApplySensorModel(const cv::Mat1f& radiance, const SensorOptions& options, std::uint64_t noise_seed);

}  // namespace tagsfm::synth
