// Procedural albedo: rich in corners and blobs for SIFT, but without dark
// squares that a tag detector could take for a tag border.
#include <algorithm>
#include <cmath>

#include <opencv2/imgproc.hpp>

#include "tagsfm/synth/scene_builder.h"

namespace tagsfm::synth {
namespace {

// Adds one octave of value noise with cells of `cell_m` metres.
void AddValueNoise(cv::Mat1f* texture, double texel_m, double cell_m, double amplitude, cv::RNG& rng) {
  const int gx = std::max(2, static_cast<int>(std::ceil(texture->cols * texel_m / cell_m)) + 1);
  const int gy = std::max(2, static_cast<int>(std::ceil(texture->rows * texel_m / cell_m)) + 1);
  cv::Mat1f grid(gy, gx);
  rng.fill(grid, cv::RNG::UNIFORM, -amplitude, amplitude);
  cv::Mat1f smooth;
  cv::resize(grid, smooth, texture->size(), 0, 0, cv::INTER_CUBIC);
  *texture += smooth;
}

int ToPx(double metres, double texel_m) { return std::max(1, static_cast<int>(std::lround(metres / texel_m))); }

// Filled ellipses of random grey.
void DrawBlobs(cv::Mat1b* canvas, double texel_m, int count, cv::RNG& rng) {
  for (int i = 0; i < count; ++i) {
    const cv::Point centre(rng.uniform(0, canvas->cols), rng.uniform(0, canvas->rows));
    const cv::Size axes(ToPx(rng.uniform(0.004, 0.04), texel_m), ToPx(rng.uniform(0.004, 0.04), texel_m));
    const double grey = rng.uniform(50.0, 210.0);
    cv::ellipse(*canvas, centre, axes, rng.uniform(0.0, 180.0), 0, 360, cv::Scalar(grey), cv::FILLED, cv::LINE_AA);
  }
}

// Short handwriting-like words: chains of strokes with random turns.
void DrawStrokes(cv::Mat1b* canvas, double texel_m, int words, cv::RNG& rng) {
  for (int w = 0; w < words; ++w) {
    cv::Point2d pen(rng.uniform(0, canvas->cols), rng.uniform(0, canvas->rows));
    const double direction = rng.uniform(0.0, CV_PI);
    const double grey = rng.uniform(0, 2) ? rng.uniform(35.0, 90.0) : rng.uniform(170.0, 225.0);
    const int thickness = ToPx(rng.uniform(0.0015, 0.004), texel_m);
    const int glyphs = rng.uniform(3, 8);
    for (int g = 0; g < glyphs; ++g) {
      cv::Point2d p = pen;
      const int strokes = rng.uniform(2, 4);
      for (int s = 0; s < strokes; ++s) {
        const double angle = rng.uniform(0.0, 2 * CV_PI);
        const double length = rng.uniform(0.005, 0.015) / texel_m;
        const cv::Point2d q = p + cv::Point2d(std::cos(angle), std::sin(angle)) * length;
        cv::line(*canvas, p, q, cv::Scalar(grey), thickness, cv::LINE_AA);
        p = q;
      }
      pen += cv::Point2d(std::cos(direction), std::sin(direction)) * (0.014 / texel_m);
    }
  }
}

}  // namespace

cv::Mat1f MakeTexture(int cols, int rows, double texel_m, std::uint64_t seed) {
  cv::RNG rng(seed * 0x9E3779B97F4A7C15ULL + 0x1234567ULL);
  cv::Mat1f texture(rows, cols, 0.5f);
  // Octaves from 40 cm down to 4 mm, all above the texel so nothing aliases.
  const double cells[] = {0.4, 0.15, 0.06, 0.025, 0.01, 0.004};
  const double amplitudes[] = {0.12, 0.10, 0.08, 0.07, 0.06, 0.05};
  for (size_t i = 0; i < std::size(cells); ++i) {
    if (cells[i] >= 2 * texel_m) AddValueNoise(&texture, texel_m, cells[i], amplitudes[i], rng);
  }
  cv::Mat1b canvas;
  texture.convertTo(canvas, CV_8U, 255.0);
  const double area_m2 = cols * rows * texel_m * texel_m;
  DrawBlobs(&canvas, texel_m, static_cast<int>(area_m2 * 150), rng);
  DrawStrokes(&canvas, texel_m, static_cast<int>(area_m2 * 120), rng);
  cv::Mat1f albedo;
  canvas.convertTo(albedo, CV_32F, 1.0 / 255.0);
  // Keep the texture out of the tag's black and white so tags stand out.
  cv::max(albedo, 0.12, albedo);
  cv::min(albedo, 0.85, albedo);
  return albedo;
}

}  // namespace tagsfm::synth
