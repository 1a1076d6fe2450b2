#pragma once
// Measures where a tag's corners are in a rendered image WITHOUT a tag
// detector: along each outer edge of the black square, the edge crossing is
// located on intensity profiles across the edge (area method: for a step from
// black B to white W, the integral of (W - I) / (W - B) over [-S, S] is the
// crossing's distance from -S), lines are fitted to those crossings in
// undistorted coordinates, and adjacent lines are intersected.
#include <array>
#include <cmath>
#include <optional>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Eigenvalues>
#include <opencv2/core.hpp>

#include "tagsfm/core/camera_model.h"
#include "tagsfm/core/rigid3d.h"
#include "tagsfm/synth/scene.h"

namespace tagsfm::synth::testing {

inline double Bilinear(const cv::Mat& gray, double x, double y) {
  const int x0 = static_cast<int>(std::floor(x)), y0 = static_cast<int>(std::floor(y));
  const double fx = x - x0, fy = y - y0;
  auto at = [&](int c, int r) { return static_cast<double>(gray.at<std::uint8_t>(r, c)); };
  return (at(x0, y0) * (1 - fx) + at(x0 + 1, y0) * fx) * (1 - fy) + (at(x0, y0 + 1) * (1 - fx) + at(x0 + 1, y0 + 1) * fx) * fy;
}

// A line a x + b y = c (a^2 + b^2 = 1) through points, by total least squares.
inline Eigen::Vector3d FitLine(const std::vector<Eigen::Vector2d>& points) {
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  for (const auto& p : points) mean += p;
  mean /= static_cast<double>(points.size());
  Eigen::Matrix2d scatter = Eigen::Matrix2d::Zero();
  for (const auto& p : points) scatter += (p - mean) * (p - mean).transpose();
  const Eigen::Vector2d normal = Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>(scatter).eigenvectors().col(0);
  return {normal.x(), normal.y(), normal.dot(mean)};
}

inline Eigen::Vector2d Intersect(const Eigen::Vector3d& l1, const Eigen::Vector3d& l2) {
  Eigen::Matrix2d a;
  a << l1.x(), l1.y(), l2.x(), l2.y();
  return a.inverse() * Eigen::Vector2d(l1.z(), l2.z());
}

struct MeasuredCorners {
  std::array<Eigen::Vector2d, 4> projected;  // the truth, by CameraModel::Project
  std::array<Eigen::Vector2d, 4> measured;   // from the rendered edges
  double max_error_px = 0;
};

// nullopt when the tag is too small (black border under 4.4 px) or too close
// to the image border to measure.
inline std::optional<MeasuredCorners> MeasureTagCorners(const cv::Mat& gray, const CameraModel& camera,
                                                        const Rigid3d& cam_from_world, const TagCorners& corners,
                                                        const TagPattern& pattern) {
  MeasuredCorners result;
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  for (const auto& c : corners) centre += c / 4;
  for (int i = 0; i < 4; ++i) result.projected[i] = camera.Project(cam_from_world * corners[i]);
  std::array<Eigen::Vector3d, 4> lines;  // in normalised image coordinates
  for (int e = 0; e < 4; ++e) {
    const Eigen::Vector3d a = corners[e], b = corners[(e + 1) % 4];
    const Eigen::Vector3d outward = ((a + b) / 2 - centre).normalized();
    const double module_m = (b - a).norm() / pattern.width_at_border;
    std::vector<Eigen::Vector2d> crossings;
    for (int k = 0; k < 41; ++k) {
      // Most of the edge, to keep the lever arm to the corners short, but
      // clear of the corners' own transitions.
      const double t = 0.1 + 0.8 * k / 40.0;
      const Eigen::Vector3d on_edge = a + t * (b - a);
      const Eigen::Vector2d q = camera.Project(cam_from_world * on_edge);
      const Eigen::Vector2d q_out = camera.Project(cam_from_world * (on_edge + 0.01 * module_m * outward));
      const Eigen::Vector2d n = (q_out - q).normalized();
      const double module_px = (camera.Project(cam_from_world * (on_edge + module_m * outward)) - q).norm();
      // The profile must reach clean black and white at both ends: a sample
      // reads pixels up to sqrt(2) px away whose footprints reach 0.71 px
      // further, so the ends are >= 2.2 px from the edge and <= 2.2 px inside
      // the 1-module black border.
      const double half = std::min(module_px - 2.2, 4.0);
      if (half < 2.2) return std::nullopt;
      if (q.x() - half - 2 < 0 || q.y() - half - 2 < 0 || q.x() + half + 2 > gray.cols - 1 ||
          q.y() + half + 2 > gray.rows - 1) {
        return std::nullopt;
      }
      const double black = Bilinear(gray, q.x() - half * n.x(), q.y() - half * n.y());
      const double white = Bilinear(gray, q.x() + half * n.x(), q.y() + half * n.y());
      if (white - black < 50) return std::nullopt;  // not the clean black/white edge
      const int steps = static_cast<int>(std::ceil(2 * half / 0.02));
      const double ds = 2 * half / steps;
      double area = 0;
      for (int s = 0; s < steps; ++s) {
        const double along = -half + (s + 0.5) * ds;
        area += (white - Bilinear(gray, q.x() + along * n.x(), q.y() + along * n.y())) / (white - black) * ds;
      }
      crossings.push_back(q + (area - half) * n);
    }
    lines[e] = FitLine(camera.PixelsToNormalized(crossings));
  }
  for (int i = 0; i < 4; ++i) {
    // Corner i is where edge (i-1 -> i) meets edge (i -> i+1).
    const Eigen::Vector2d normalized = Intersect(lines[(i + 3) % 4], lines[i]);
    result.measured[i] = camera.Project(Eigen::Vector3d(normalized.x(), normalized.y(), 1.0));
    result.max_error_px = std::max(result.max_error_px, (result.measured[i] - result.projected[i]).norm());
  }
  return result;
}

// True when every corner of the tag is seen: the face turned towards the
// camera (less than 70 degrees off), and no other face in the way.
inline bool TagFullyVisible(const Scene& scene, const PlacedTag& tag, const Rigid3d& cam_from_world) {
  const Eigen::Vector3d eye = cam_from_world.Center();
  const TagCorners corners = TagCornersInWorld(scene, tag);
  const Rectangle3d& rect = scene.faces[static_cast<size_t>(tag.face)].rect;
  const Eigen::Vector3d to_eye = (eye - corners[0]).normalized();
  if (rect.Normal().dot(to_eye) < std::cos(70 * M_PI / 180)) return false;
  for (const Eigen::Vector3d& corner : corners) {
    const Eigen::Vector3d ray = corner - eye;
    for (size_t f = 0; f < scene.faces.size(); ++f) {
      if (static_cast<int>(f) == tag.face) continue;
      const Rectangle3d& other = scene.faces[f].rect;
      const Eigen::Vector3d normal = other.edge_u.cross(other.edge_v);
      const double denominator = normal.dot(ray);
      if (std::abs(denominator) < 1e-12) continue;
      const double t = normal.dot(other.origin - eye) / denominator;
      if (t <= 1e-6 || t >= 1 - 1e-6) continue;
      const Eigen::Vector3d hit = eye + t * ray - other.origin;
      const double a = hit.dot(other.edge_u) / other.edge_u.squaredNorm();
      const double b = hit.dot(other.edge_v) / other.edge_v.squaredNorm();
      if (a >= 0 && a <= 1 && b >= 0 && b <= 1) return false;
    }
  }
  return true;
}

}  // namespace tagsfm::synth::testing
