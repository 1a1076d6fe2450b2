#include "tagsfm/detect/synthetic_tags.h"

#include <algorithm>
#include <cmath>
#include <optional>
#include <random>

#include <Eigen/Geometry>
#include <opencv2/imgproc.hpp>

#include "apriltag_family.h"
#include "tagsfm/detect/tag_layout.h"

namespace tagsfm {
namespace {

struct ImageU8Deleter {
  void operator()(image_u8_t* image) const { image_u8_destroy(image); }
};

// Fibonacci lattice: 987 points, the i-th at ((i + 0.5) / 987, frac((610 i + 0.5) / 987)).
constexpr int kFineSamples = 987;
constexpr int kFibonacciStep = 610;

// Canvas coordinates (possibly `scale` times finer than the image, pixel
// centre x at scale x + shift) to the undistorted image coordinates the
// tags' corners are given in (the same scale), and back.
class CanvasMap {
 public:
  CanvasMap(const CameraModel* camera, double scale) : camera_(camera), scale_(scale), shift_(0.5 * (scale - 1.0)) {}

  Eigen::Vector2d ToScene(double x, double y) const {
    if (camera_ == nullptr) return {x, y};
    const Eigen::Vector2d d(((x - shift_) / scale_ - camera_->cx) / camera_->fx,
                            ((y - shift_) / scale_ - camera_->cy) / camera_->fy);
    const Eigen::Vector2d n = Undistort(d);
    return {scale_ * (camera_->fx * n.x() + camera_->cx) + shift_, scale_ * (camera_->fy * n.y() + camera_->cy) + shift_};
  }
  Eigen::Vector2d ToCanvas(const Eigen::Vector2d& scene) const {
    if (camera_ == nullptr) return scene;
    const Eigen::Vector2d u = (scene - Eigen::Vector2d(shift_, shift_)) / scale_;
    const Eigen::Vector2d d =
        camera_->Project(Eigen::Vector3d((u.x() - camera_->cx) / camera_->fx, (u.y() - camera_->cy) / camera_->fy, 1.0));
    return scale_ * d + Eigen::Vector2d(shift_, shift_);
  }

 private:
  // OpenCV's radial-tangential model (k1, k2, p1, p2, k3) inverted by
  // fixed-point iteration, to ~1e-12 for the moderate distortions of tests.
  Eigen::Vector2d Undistort(const Eigen::Vector2d& distorted) const {
    const std::vector<double>& c = camera_->distortion;
    auto k = [&](size_t i) { return i < c.size() ? c[i] : 0.0; };
    Eigen::Vector2d n = distorted;
    for (int it = 0; it < 30; ++it) {
      const double r2 = n.squaredNorm();
      const double radial = 1.0 + r2 * (k(0) + r2 * (k(1) + r2 * k(4)));
      const double dx = 2.0 * k(2) * n.x() * n.y() + k(3) * (r2 + 2.0 * n.x() * n.x());
      const double dy = k(2) * (r2 + 2.0 * n.y() * n.y()) + 2.0 * k(3) * n.x() * n.y();
      n = Eigen::Vector2d((distorted.x() - dx) / radial, (distorted.y() - dy) / radial);
    }
    return n;
  }

  const CameraModel* camera_;
  double scale_;
  double shift_;
};

// Draws each tag (bitmap plus paper margin) into `canvas`, every pixel
// integrated over its area: a coarse `supersample` grid per axis finds the
// pixels an edge crosses, and those are integrated on a Fibonacci lattice of
// `fine_samples` points (`fine_step` its generator), whose points all differ
// in x and in y, so an edge at any angle is placed to 1/fine_samples px (a
// regular grid would quantise an axis-aligned edge to 1/supersample px).
// One tag as the raster draws it: its bitmap placed in the image by a
// homography, the white paper round it and its shade.
struct TagRaster {
  std::unique_ptr<image_u8_t, ImageU8Deleter> bitmap;
  const CanvasMap* map = nullptr;
  Eigen::Matrix3d image_from_square, square_from_image;
  int total = 0;              // the bitmap's width, modules (its own white ring included)
  double border_start = 0.0;  // where the detector's square starts in the bitmap, modules
  double across = 0.0;        // the detector's square's width, modules
  double paper = 0.0;         // the white margin beyond the bitmap's own ring, modules
  double white = 0.0, black = 0.0;

  // Value of the bitmap (or -1 outside it and its paper) at an image point.
  double Value(double x, double y) const {
    const Eigen::Vector3d q = square_from_image * map->ToScene(x, y).homogeneous();
    const double bx = q.x() / q.z() + border_start;
    const double by = q.y() / q.z() + border_start;
    if (!(bx >= 0 && by >= 0 && bx < total && by < total)) {
      const bool on_paper = bx >= -paper && by >= -paper && bx < total + paper && by < total + paper;
      return on_paper ? white : -1.0;
    }
    const uint8_t bit = bitmap->buf[static_cast<int>(by) * bitmap->stride + static_cast<int>(bx)];
    return bit != 0 ? white : black;
  }
};

Result<TagRaster> MakeTagRaster(apriltag_family_t* fam, const std::string& family_name, const PlacedTag& tag,
                                const TagRenderOptions& options, const CanvasMap& map) {
  if (tag.id < 0 || tag.id >= static_cast<int>(fam->ncodes)) {
    return MakeError("RenderTags: id " + std::to_string(tag.id) + " not in " + family_name);
  }
  TagRaster raster;
  raster.bitmap.reset(apriltag_to_image(fam, tag.id));
  raster.map = &map;
  raster.total = fam->total_width;
  raster.border_start = (fam->total_width - fam->width_at_border) / 2;
  raster.across = fam->width_at_border;
  // This tag's lighting (TagRenderOptions::tag_shade_variation), from the
  // seed and the id, so it does not depend on the other tags.
  std::mt19937_64 shade_rng(options.seed * 0x9E3779B97F4A7C15ULL + static_cast<std::uint64_t>(tag.id));
  const double shade = 1.0 - options.tag_shade_variation * std::uniform_real_distribution<double>(0.0, 1.0)(shade_rng);
  raster.white = shade * options.white;
  raster.black = shade * options.black;
  raster.paper = std::max(0.0, options.margin_modules - raster.border_start);
  // Corner-square coordinates (modules, x right, y down, origin at the
  // square's top-left) of libapriltag's corners 0..3: bottom-left,
  // bottom-right, top-right, top-left.
  const QuadCorners square = CornerSquareCorners(fam->width_at_border);
  const std::optional<Eigen::Matrix3d> homography = HomographyFrom4(square, tag.corners);
  if (!homography) return MakeError("RenderTags: degenerate corners for tag " + std::to_string(tag.id));
  raster.image_from_square = *homography;
  raster.square_from_image = homography->inverse();
  return raster;
}

// The pixels [x0, x1] x [y0, y1] the bitmap with its paper can touch.
struct PixelBox {
  int x0 = 0, x1 = -1, y0 = 0, y1 = -1;
};
PixelBox PixelsTouched(const TagRaster& raster, int width, int height, bool distorted) {
  double x_min = 1e9, x_max = -1e9, y_min = 1e9, y_max = -1e9;
  const double reach = raster.border_start + raster.paper;
  for (double u : {-reach, raster.across + reach}) {
    for (double v : {-reach, raster.across + reach}) {
      const Eigen::Vector2d p = raster.map->ToCanvas((raster.image_from_square * Eigen::Vector3d(u, v, 1.0)).hnormalized());
      x_min = std::min(x_min, p.x());
      x_max = std::max(x_max, p.x());
      y_min = std::min(y_min, p.y());
      y_max = std::max(y_max, p.y());
    }
  }
  // (Under distortion the sides bow: a wider margin.)
  const int margin = distorted ? 2 + static_cast<int>(0.05 * (x_max - x_min + y_max - y_min)) : 1;
  return {std::max(0, static_cast<int>(std::floor(x_min)) - margin),
          std::min(width - 1, static_cast<int>(std::ceil(x_max)) + margin),
          std::max(0, static_cast<int>(std::floor(y_min)) - margin),
          std::min(height - 1, static_cast<int>(std::ceil(y_max)) + margin)};
}

// Pixel (x, y)'s value with the tag drawn over `under`: the bitmap's where
// all of a coarse `supersample` grid agrees, else the mean over the fine
// lattice (see DrawTags), `under` where a sample falls off the paper.
float PixelValue(const TagRaster& raster, int x, int y, int supersample, int fine_samples, int fine_step, float under) {
  const int s = supersample;
  const double first = raster.Value(x - 0.5 + 0.5 / s, y - 0.5 + 0.5 / s);
  bool uniform = true;
  for (int sy = 0; sy < s && uniform; ++sy) {
    for (int sx = 0; sx < s && uniform; ++sx) {
      uniform = raster.Value(x - 0.5 + (sx + 0.5) / s, y - 0.5 + (sy + 0.5) / s) == first;
    }
  }
  if (uniform) return first >= 0.0 ? static_cast<float>(first) : under;
  double sum = 0.0;
  for (int i = 0; i < fine_samples; ++i) {
    const double fx = (i + 0.5) / fine_samples;
    const double fy = std::fmod((static_cast<double>(i) * fine_step + 0.5) / fine_samples, 1.0);
    const double v = raster.Value(x - 0.5 + fx, y - 0.5 + fy);
    sum += v >= 0.0 ? v : under;
  }
  return static_cast<float>(sum / fine_samples);
}

Status DrawTags(apriltag_family_t* fam, const std::string& family_name, const std::vector<PlacedTag>& tags,
                const TagRenderOptions& options, const CanvasMap& map, int supersample, int fine_samples, int fine_step,
                cv::Mat* canvas) {
  for (const PlacedTag& tag : tags) {
    Result<TagRaster> raster = MakeTagRaster(fam, family_name, tag, options, map);
    if (!raster) return raster.error();
    const PixelBox box = PixelsTouched(*raster, canvas->cols, canvas->rows, options.camera != nullptr);
    for (int y = box.y0; y <= box.y1; ++y) {
      float* row = canvas->ptr<float>(y);
      for (int x = box.x0; x <= box.x1; ++x) row[x] = PixelValue(*raster, x, y, supersample, fine_samples, fine_step, row[x]);
    }
  }
  return Status::Ok();
}

// The background: `background` plus value noise (cells of 40, 12 and 4 px)
// and filled blobs and strokes of random grey, drawn on a canvas `scale`
// times finer than the image (blobs 1-8 px, strokes 1-3 px wide: the tags'
// margins meet edges of every contrast and scale). Clipped to [black, white
// - 20] so that the margin stays the brightest thing round a tag.
cv::Mat MakeBackground(int width, int height, int scale, const TagRenderOptions& options) {
  cv::Mat canvas(height * scale, width * scale, CV_32F, cv::Scalar(options.background));
  if (options.texture_contrast <= 0.0) return canvas;
  cv::RNG rng(options.seed * 0x2545F4914F6CDD1DULL + 99);
  const double c = options.texture_contrast;
  for (double cell_px : {40.0, 12.0, 4.0}) {
    cv::Mat grid(static_cast<int>(height / cell_px) + 2, static_cast<int>(width / cell_px) + 2, CV_32F);
    rng.fill(grid, cv::RNG::UNIFORM, -0.4 * c, 0.4 * c);
    cv::Mat smooth;
    cv::resize(grid, smooth, canvas.size(), 0, 0, cv::INTER_CUBIC);
    canvas += smooth;
  }
  auto grey = [&] { return cv::Scalar(options.background + rng.uniform(-c, c)); };
  const int blobs = width * height / 150, strokes = width * height / 300;
  for (int i = 0; i < blobs; ++i) {
    const cv::Point centre(rng.uniform(0, canvas.cols), rng.uniform(0, canvas.rows));
    const cv::Size axes(static_cast<int>(scale * rng.uniform(0.5, 4.0)), static_cast<int>(scale * rng.uniform(0.5, 4.0)));
    cv::ellipse(canvas, centre, axes, rng.uniform(0.0, 180.0), 0, 360, grey(), cv::FILLED, cv::LINE_AA);
  }
  for (int i = 0; i < strokes; ++i) {
    const cv::Point a(rng.uniform(0, canvas.cols), rng.uniform(0, canvas.rows));
    const double angle = rng.uniform(0.0, 2 * CV_PI), length = scale * rng.uniform(2.0, 10.0);
    const cv::Point b(a.x + static_cast<int>(length * std::cos(angle)), a.y + static_cast<int>(length * std::sin(angle)));
    cv::line(canvas, a, b, grey(), std::max(1, static_cast<int>(scale * rng.uniform(1.0, 3.0))), cv::LINE_AA);
  }
  cv::max(canvas, options.black, canvas);
  cv::min(canvas, options.white - 20.0, canvas);
  return canvas;
}

}  // namespace

Result<cv::Mat> RenderTags(const std::string& family_name, int width, int height, const std::vector<PlacedTag>& tags,
                           const TagRenderOptions& options) {
  if (width <= 0 || height <= 0) return MakeError("RenderTags: image size must be positive");
  if (options.supersample < 1) return MakeError("RenderTags: supersample must be >= 1");
  if (!(options.margin_modules >= 1.0) || options.margin_modules > 10.0) {
    return MakeError("RenderTags: margin_modules must be in 1..10");
  }
  if (!(options.tag_shade_variation >= 0.0 && options.tag_shade_variation < 1.0)) {
    return MakeError("RenderTags: tag_shade_variation must be in [0, 1)");
  }
  if (options.blur_oversample < 1 || options.blur_oversample > 8) {
    return MakeError("RenderTags: blur_oversample must be in 1..8");
  }
  if (options.camera != nullptr && options.camera->HasDistortion() &&
      (options.camera->kind != CameraModel::Kind::kPinhole || options.camera->distortion.size() > 5)) {
    return MakeError("RenderTags: distortion rendering supports the pinhole model's k1, k2, p1, p2, k3 only");
  }
  Result<detail::FamilyPtr> family = detail::CreateAprilTagFamily(family_name);
  if (!family) return family.error();

  cv::Mat canvas;
  const int f = options.blur_sigma_px > 0.0 ? options.blur_oversample : 1;
  if (f == 1) {
    canvas = MakeBackground(width, height, 1, options);
    Status drawn = DrawTags(family->get(), family_name, tags, options, CanvasMap(options.camera, 1.0),
                            options.supersample, kFineSamples, kFibonacciStep, &canvas);
    if (!drawn) return drawn.error();
    if (options.blur_sigma_px > 0.0) {
      cv::GaussianBlur(canvas, canvas, cv::Size(0, 0), options.blur_sigma_px, 0.0, cv::BORDER_REFLECT);
    }
  } else {
    // The optics blur the scene before the pixels integrate it. Blurring
    // the area-averaged pixels instead (a sampled Gaussian on the pixel
    // grid) is a different, non-physical response for blurs below ~1 px: it
    // biased the edge fit by ~-0.002 px on 3 px modules at 0.7 px blur
    // (docs/detection.md). So: draw f times finer (pixel centre x maps to
    // f x + (f - 1) / 2), blur there, then average f x f blocks.
    std::vector<PlacedTag> fine_tags = tags;
    const Eigen::Vector2d shift(0.5 * (f - 1), 0.5 * (f - 1));
    for (PlacedTag& tag : fine_tags) {
      for (Eigen::Vector2d& c : tag.corners) c = f * c + shift;
    }
    cv::Mat fine = MakeBackground(width, height, f, options);
    // The same absolute precision as at f = 1: 144 lattice points per fine
    // pixel are ~2300 per output pixel.
    Status drawn = DrawTags(family->get(), family_name, fine_tags, options, CanvasMap(options.camera, f),
                            std::max(2, (options.supersample + f - 1) / f), 144, 89, &fine);
    if (!drawn) return drawn.error();
    cv::GaussianBlur(fine, fine, cv::Size(0, 0), f * options.blur_sigma_px, 0.0, cv::BORDER_REFLECT);
    cv::resize(fine, canvas, cv::Size(width, height), 0.0, 0.0, cv::INTER_AREA);
  }
  if (options.noise_sigma > 0.0) {
    std::mt19937_64 rng(options.seed);
    std::normal_distribution<float> noise(0.0f, static_cast<float>(options.noise_sigma));
    for (int y = 0; y < height; ++y) {
      float* row = canvas.ptr<float>(y);
      for (int x = 0; x < width; ++x) row[x] += noise(rng);
    }
  }
  cv::Mat image;
  canvas.convertTo(image, CV_8U);  // rounds and saturates
  return image;
}

PlacedTag TagSeenFromOneMetre(int id, double cx, double cy, double side_px, const Eigen::Matrix3d& rotation) {
  const double focal = 1000.0;  // a moderate perspective, like a 60 degree lens
  const double half = 0.5 * side_px / focal;
  const std::array<Eigen::Vector3d, 4> in_tag{Eigen::Vector3d(-half, half, 0), Eigen::Vector3d(half, half, 0),
                                              Eigen::Vector3d(half, -half, 0), Eigen::Vector3d(-half, -half, 0)};
  PlacedTag tag;
  tag.id = id;
  for (int k = 0; k < 4; ++k) {
    const Eigen::Vector3d p = rotation * in_tag[k] + Eigen::Vector3d(0, 0, 1.0);
    tag.corners[k] = Eigen::Vector2d(cx + focal * p.x() / p.z(), cy + focal * p.y() / p.z());
  }
  return tag;
}

std::vector<PlacedTag> RandomTagPlacements(int width, int height, int count, double side_px, double max_tilt_deg,
                                           std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  // Grid cells of 2.2 tag sides leave room for tilt, margins and jitter.
  const double cell = 2.2 * side_px;
  const int columns = static_cast<int>((width - side_px) / cell);
  const int rows = static_cast<int>((height - side_px) / cell);
  std::vector<PlacedTag> placed;
  const int cells = columns * rows;
  for (int i = 0; i < count && i < cells; ++i) {
    // Spread over the whole grid, not packed into its first rows.
    const int c = static_cast<int>(static_cast<long long>(i) * cells / std::min(count, cells));
    const double cx = side_px / 2 + cell * (c % columns + 0.5) + (unit(rng) - 0.5) * 0.3 * side_px;
    const double cy = side_px / 2 + cell * (c / columns + 0.5) + (unit(rng) - 0.5) * 0.3 * side_px;
    const double tilt = max_tilt_deg * M_PI / 180.0 * unit(rng);
    const double tilt_axis = 2.0 * M_PI * unit(rng);
    const double spin = 2.0 * M_PI * unit(rng);
    const Eigen::Matrix3d rotation =
        (Eigen::AngleAxisd(spin, Eigen::Vector3d::UnitZ()) *
         Eigen::AngleAxisd(tilt, Eigen::Vector3d(std::cos(tilt_axis), std::sin(tilt_axis), 0.0)))
            .toRotationMatrix();
    placed.push_back(TagSeenFromOneMetre(i, cx, cy, side_px, rotation));
  }
  return placed;
}

std::vector<std::vector<PlacedTag>> VideoTagPlacements(int width, int height, int count, double side_px, int frames,
                                                       double pan_px_per_frame, std::uint64_t seed) {
  const std::vector<PlacedTag> start = RandomTagPlacements(width, height, count, side_px, 50.0, seed);
  std::mt19937_64 rng(seed + 1);
  std::normal_distribution<double> shake(0.0, 0.7);
  const Eigen::Vector2d center(0.5 * width, 0.5 * height);
  std::vector<std::vector<PlacedTag>> sequence;
  for (int f = 0; f < frames; ++f) {
    const Eigen::Rotation2Dd roll(0.1 * M_PI / 180.0 * f);
    const Eigen::Vector2d shift = Eigen::Vector2d(pan_px_per_frame, 0.5 * pan_px_per_frame) * f +
                                  Eigen::Vector2d(shake(rng), shake(rng)) -
                                  Eigen::Vector2d(pan_px_per_frame, 0.5 * pan_px_per_frame) * (0.5 * frames);
    std::vector<PlacedTag> frame;
    for (const PlacedTag& tag : start) {
      PlacedTag moved = tag;
      bool inside = true;
      for (Eigen::Vector2d& c : moved.corners) {
        c = center + roll * (c - center) + shift;
        inside = inside && c.x() > 2 && c.y() > 2 && c.x() < width - 3 && c.y() < height - 3;
      }
      if (inside) frame.push_back(moved);
    }
    sequence.push_back(std::move(frame));
  }
  return sequence;
}

}  // namespace tagsfm
