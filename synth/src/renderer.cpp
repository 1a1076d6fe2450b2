// The ray-caster. Per sample: a ray from the pixel-corner table, nearest hit
// among the faces (each plane's hit is a few multiply-adds in the camera
// frame), albedo from a tag's modules or the face texture.
#include "tagsfm/synth/renderer.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <thread>

#include <opencv2/imgproc.hpp>

namespace tagsfm::synth {
namespace {

constexpr float kTagBlack = 0.06f;
constexpr float kTagWhite = 0.92f;  // white paper and the tag's white modules
constexpr double kNearZ = 1e-3;

// A face expressed in the current camera frame, ready for ray tests with
// rays r = (x, y, 1): depth = plane_d / normal.r, and the hit's face
// coordinates a = depth * u.r - u_offset, b = depth * v.r - v_offset in [0, 1].
struct FaceInCamera {
  Eigen::Vector3d normal, u, v;
  double plane_d, u_offset, v_offset;
};

// A tag in its face's (a, b) coordinates: module (col, row) of a hit.
struct TagInFace {
  const PlacedTag* tag;
  Eigen::Vector2d centre_ab;
  // (a, b) -> module coordinates relative to the tag's centre, in modules.
  Eigen::Matrix2d modules_from_ab;
  double half_sheet_modules;  // the detector's square plus the white margin (at least the tag image)
};

struct FaceShading {
  const SceneFace* face;
  std::vector<TagInFace> tags;
};

// Deterministic per-sample jitter in [0, 1): a 64-bit mix of pixel and sample.
inline double Jitter(std::uint64_t key) {
  key ^= key >> 33;
  key *= 0xff51afd7ed558ccdULL;
  key ^= key >> 33;
  key *= 0xc4ceb9fe1a85ec53ULL;
  key ^= key >> 33;
  return static_cast<double>(key >> 11) * (1.0 / 9007199254740992.0);
}

float SampleTexture(const cv::Mat1f& texture, double a, double b) {
  const double x = std::clamp(a * texture.cols - 0.5, 0.0, texture.cols - 1.0);
  const double y = std::clamp(b * texture.rows - 0.5, 0.0, texture.rows - 1.0);
  const int x0 = std::min(static_cast<int>(x), texture.cols - 2 < 0 ? 0 : texture.cols - 2);
  const int y0 = std::min(static_cast<int>(y), texture.rows - 2 < 0 ? 0 : texture.rows - 2);
  const int x1 = std::min(x0 + 1, texture.cols - 1), y1 = std::min(y0 + 1, texture.rows - 1);
  const float fx = static_cast<float>(x - x0), fy = static_cast<float>(y - y0);
  const float* r0 = texture.ptr<float>(y0);
  const float* r1 = texture.ptr<float>(y1);
  return (r0[x0] * (1 - fx) + r0[x1] * fx) * (1 - fy) + (r1[x0] * (1 - fx) + r1[x1] * fx) * fy;
}

float Albedo(const FaceShading& shading, double a, double b) {
  for (const TagInFace& t : shading.tags) {
    const Eigen::Vector2d m = t.modules_from_ab * (Eigen::Vector2d(a, b) - t.centre_ab);
    if (std::abs(m.x()) >= t.half_sheet_modules || std::abs(m.y()) >= t.half_sheet_modules) continue;
    const TagPattern& p = t.tag->pattern;
    // Module grid: column to the right, row downwards from the top edge.
    const double col = m.x() + 0.5 * p.total_width;
    const double row = 0.5 * p.total_width - m.y();
    if (col < 0 || row < 0 || col >= p.total_width || row >= p.total_width) return kTagWhite;
    return p.WhiteAt(static_cast<int>(col), static_cast<int>(row)) ? kTagWhite : kTagBlack;
  }
  return SampleTexture(shading.face->texture, a, b);
}

std::vector<FaceShading> ShadingOf(const Scene& scene) {
  std::vector<FaceShading> shading(scene.faces.size());
  for (size_t f = 0; f < scene.faces.size(); ++f) shading[f].face = &scene.faces[f];
  for (const PlacedTag& tag : scene.tags) {
    const Rectangle3d& rect = scene.faces[static_cast<size_t>(tag.face)].rect;
    const double lu = rect.edge_u.norm(), lv = rect.edge_v.norm();
    const double module_m = tag.size_m / tag.pattern.width_at_border;
    const double c = std::cos(tag.angle_rad), s = std::sin(tag.angle_rad);
    TagInFace t;
    t.tag = &tag;
    t.centre_ab = Eigen::Vector2d(tag.centre_in_face.x() / lu, tag.centre_in_face.y() / lv);
    // metres in face = (a lu, b lv); module x along (c, s), module y along (-s, c).
    Eigen::Matrix2d modules_from_m;
    modules_from_m << c, s, -s, c;
    t.modules_from_ab = modules_from_m * Eigen::Vector2d(lu, lv).asDiagonal() / module_m;
    t.half_sheet_modules = std::max(0.5 * tag.pattern.total_width, 0.5 * tag.pattern.width_at_border + tag.margin_modules);
    shading[static_cast<size_t>(tag.face)].tags.push_back(t);
  }
  return shading;
}

}  // namespace

Result<SceneRenderer> SceneRenderer::Create(const CameraModel& camera, const Scene* scene, int samples, int threads) {
  if (Status s = camera.Check(); !s) return s.error();
  if (scene == nullptr || scene->faces.empty()) return MakeError("synth: the scene has no faces");
  if (samples < 1 || threads < 1) return MakeError("synth: samples and threads must be >= 1");
  SceneRenderer renderer;
  renderer.camera_ = camera;
  renderer.scene_ = scene;
  renderer.samples_ = samples;
  renderer.threads_ = threads;
  std::vector<Eigen::Vector2d> corners;
  corners.reserve(static_cast<size_t>(camera.width + 1) * (camera.height + 1));
  for (int i = 0; i <= camera.height; ++i) {
    for (int j = 0; j <= camera.width; ++j) corners.emplace_back(j - 0.5, i - 0.5);
  }
  renderer.corner_rays_ = camera.PixelsToNormalized(corners);
  for (const Eigen::Vector2d& ray : renderer.corner_rays_) {
    if (!ray.allFinite()) return MakeError("synth: the distortion cannot be inverted over the whole image");
  }
  return renderer;
}

cv::Mat1f SceneRenderer::Render(const Rigid3d& cam_from_world, double blur_px) const {
  const bool per_sample = blur_px > 0.0;
  const int scale = per_sample ? samples_ : 1;
  cv::Mat1f out(camera_.height * scale, camera_.width * scale);
  std::vector<std::thread> workers;
  for (int t = 1; t < threads_; ++t) {
    workers.emplace_back([&, t] { RenderRows(cam_from_world, t, threads_, per_sample, &out); });
  }
  RenderRows(cam_from_world, 0, threads_, per_sample, &out);
  for (std::thread& w : workers) w.join();
  if (!per_sample) return out;
  // The lens blurs the radiance on the sample grid; the pixels then average
  // their samples (INTER_AREA at an integer factor is that block mean).
  cv::GaussianBlur(out, out, cv::Size(), blur_px * scale, blur_px * scale, cv::BORDER_REFLECT);
  cv::Mat1f pixels;
  cv::resize(out, pixels, cv::Size(camera_.width, camera_.height), 0, 0, cv::INTER_AREA);
  return pixels;
}

void SceneRenderer::RenderRows(const Rigid3d& cam_from_world, int first_row, int row_step, bool per_sample,
                               cv::Mat1f* out) const {
  const Eigen::Matrix3d rotation = cam_from_world.RotationMatrix();
  std::vector<FaceInCamera> faces;
  std::vector<int> face_index;
  for (size_t i = 0; i < scene_->faces.size(); ++i) {
    const SceneFace& face = scene_->faces[i];
    FaceInCamera f;
    const Eigen::Vector3d origin = cam_from_world * face.rect.origin;
    const Eigen::Vector3d eu = rotation * face.rect.edge_u, ev = rotation * face.rect.edge_v;
    f.normal = eu.cross(ev);
    f.plane_d = f.normal.dot(origin);
    // Faces are one-sided: one seen from behind (the camera at the origin on
    // its back side) is hidden by the front faces of the same solid.
    if (f.plane_d >= 0) continue;
    face_index.push_back(static_cast<int>(i));
    f.u = eu / eu.squaredNorm();
    f.v = ev / ev.squaredNorm();
    f.u_offset = f.u.dot(origin);
    f.v_offset = f.v.dot(origin);
    faces.push_back(f);
  }
  const std::vector<FaceShading> shading = ShadingOf(*scene_);
  const int width = camera_.width, stride = camera_.width + 1;
  const double inv_samples = 1.0 / samples_;
  const double weight = 1.0 / (samples_ * samples_);
  for (int row = first_row; row < camera_.height; row += row_step) {
    for (int col = 0; col < width; ++col) {
      const Eigen::Vector2d& c00 = corner_rays_[static_cast<size_t>(row * stride + col)];
      const Eigen::Vector2d& c10 = corner_rays_[static_cast<size_t>(row * stride + col + 1)];
      const Eigen::Vector2d& c01 = corner_rays_[static_cast<size_t>((row + 1) * stride + col)];
      const Eigen::Vector2d& c11 = corner_rays_[static_cast<size_t>((row + 1) * stride + col + 1)];
      const std::uint64_t pixel_key = (static_cast<std::uint64_t>(row) << 32 | static_cast<std::uint64_t>(col)) * 256;
      double sum = 0.0;
      for (int sy = 0; sy < samples_; ++sy) {
        for (int sx = 0; sx < samples_; ++sx) {
          const std::uint64_t key = pixel_key + static_cast<std::uint64_t>(sy * samples_ + sx) * 2;
          const double fx = (sx + Jitter(key)) * inv_samples;
          const double fy = (sy + Jitter(key + 1)) * inv_samples;
          // Bilinear in the corner table: the undistortion map is smooth, so
          // this matches per-sample undistortion to ~1e-4 px.
          const Eigen::Vector2d n = (1 - fy) * ((1 - fx) * c00 + fx * c10) + fy * ((1 - fx) * c01 + fx * c11);
          const Eigen::Vector3d ray(n.x(), n.y(), 1.0);
          double best_depth = std::numeric_limits<double>::infinity();
          int best_face = -1;
          double best_a = 0, best_b = 0;
          for (size_t f = 0; f < faces.size(); ++f) {
            const FaceInCamera& face = faces[f];
            const double denominator = face.normal.dot(ray);
            if (denominator == 0.0) continue;
            const double depth = face.plane_d / denominator;
            if (!(depth > kNearZ && depth < best_depth)) continue;
            const double a = depth * face.u.dot(ray) - face.u_offset;
            if (a < 0.0 || a > 1.0) continue;
            const double b = depth * face.v.dot(ray) - face.v_offset;
            if (b < 0.0 || b > 1.0) continue;
            best_depth = depth;
            best_face = face_index[f];
            best_a = a;
            best_b = b;
          }
          double value = scene_->background;
          if (best_face >= 0) {
            const FaceShading& s = shading[static_cast<size_t>(best_face)];
            value = s.face->shade * Albedo(s, best_a, best_b);
          }
          if (per_sample) {
            out->at<float>(row * samples_ + sy, col * samples_ + sx) = static_cast<float>(value);
          } else {
            sum += value;
          }
        }
      }
      if (!per_sample) out->at<float>(row, col) = static_cast<float>(sum * weight);
    }
  }
}

cv::Mat ApplySensorModel(const cv::Mat1f& light, const SensorOptions& options, std::uint64_t noise_seed) {
  cv::Mat1f signal = light * (255.0 * options.brightness);
  if (options.noise > 0) {
    cv::Mat1f noise(signal.size());
    cv::RNG rng(noise_seed);
    rng.fill(noise, cv::RNG::NORMAL, 0.0, options.noise);
    signal += noise;
  }
  cv::Mat gray;
  signal.convertTo(gray, CV_8U);  // rounds to nearest and saturates to 0..255
  return gray;
}

}  // namespace tagsfm::synth
