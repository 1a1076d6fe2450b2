#include "small_tag_reader.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include <Eigen/Dense>
#include <opencv2/imgproc.hpp>

namespace tagsfm::detail {
namespace {

// Grey level as a plane a + b x + c y over (x, y, grey) samples.
std::optional<Eigen::Vector3d> FitGreyPlane(const std::vector<Eigen::Vector3d>& samples) {
  Eigen::Matrix3d a = Eigen::Matrix3d::Zero();
  Eigen::Vector3d b = Eigen::Vector3d::Zero();
  for (const Eigen::Vector3d& s : samples) {
    const Eigen::Vector3d row(1.0, s.x(), s.y());
    a += row * row.transpose();
    b += row * s.z();
  }
  Eigen::LDLT<Eigen::Matrix3d> ldlt(a);
  if (ldlt.info() != Eigen::Success) return std::nullopt;
  Eigen::Vector3d plane = ldlt.solve(b);
  if (!plane.allFinite()) return std::nullopt;
  return plane;
}

}  // namespace

std::optional<double> SampleBilinear(const cv::Mat& g, double x, double y) {
  // Compared before the conversion to int: a degenerate quad's homography
  // can send a point to infinity or NaN.
  if (!(x >= 0.0 && y >= 0.0 && x < g.cols - 1 && y < g.rows - 1)) return std::nullopt;
  const int x0 = static_cast<int>(std::floor(x)), y0 = static_cast<int>(std::floor(y));
  const double fx = x - x0, fy = y - y0;
  const uint8_t* r0 = g.ptr<uint8_t>(y0);
  const uint8_t* r1 = g.ptr<uint8_t>(y0 + 1);
  return (1 - fy) * ((1 - fx) * r0[x0] + fx * r0[x0 + 1]) + fy * ((1 - fx) * r1[x0] + fx * r1[x0 + 1]);
}

std::optional<QuadReading> ReadQuad(const cv::Mat& g, const apriltag_family_t* family, const QuadCorners& q,
                                    int max_hamming, double min_contrast) {
  const int w = family->width_at_border;
  const auto tag_coord = [w](double module) { return 2.0 * (module + 0.5) / w - 1.0; };
  std::optional<QuadReading> best;
  for (int winding = 0; winding < 2; ++winding) {
    for (int start = 0; start < 4; ++start) {
      // libapriltag's order: tag (-1, 1), (1, 1), (1, -1), (-1, -1).
      std::vector<cv::Point2f> tag_pts{{-1, 1}, {1, 1}, {1, -1}, {-1, -1}}, image_pts(4);
      QuadCorners corners;
      for (int i = 0; i < 4; ++i) {
        corners[i] = q[winding ? (4 - i + start) % 4 : (i + start) % 4];
        image_pts[i] = cv::Point2f(static_cast<float>(corners[i].x()), static_cast<float>(corners[i].y()));
      }
      const cv::Matx33d h = cv::getPerspectiveTransform(tag_pts, image_pts);
      const auto project = [&h](double tx, double ty) {
        const cv::Vec3d v = h * cv::Vec3d(tx, ty, 1.0);
        return Eigen::Vector2d(v[0] / v[2], v[1] / v[2]);
      };
      std::vector<Eigen::Vector3d> black, white;
      bool inside = true;
      for (int i = -1; i <= w && inside; ++i) {
        for (int j = -1; j <= w; ++j) {
          const bool outer = i == -1 || j == -1 || i == w || j == w;
          const bool ring = !outer && (i == 0 || j == 0 || i == w - 1 || j == w - 1);
          if (!outer && !ring) continue;
          if (outer && (i == -1 || i == w) && (j == -1 || j == w)) continue;  // the white ring's corners
          const Eigen::Vector2d p = project(tag_coord(i), tag_coord(j));
          const std::optional<double> v = SampleBilinear(g, p.x(), p.y());
          if (!v) {
            inside = false;
            break;
          }
          (outer ? white : black).emplace_back(p.x(), p.y(), *v);
        }
      }
      if (!inside) return std::nullopt;  // the same samples for every order
      const std::optional<Eigen::Vector3d> black_plane = FitGreyPlane(black), white_plane = FitGreyPlane(white);
      if (!black_plane || !white_plane) return std::nullopt;
      const auto level = [](const Eigen::Vector3d& plane, double x, double y) {
        return plane.x() + plane.y() * x + plane.z() * y;
      };
      double worst = 1e9, contrast_sum = 0.0;
      int count = 0;
      bool contrasted = true;
      const auto margin_of = [&](const Eigen::Vector3d& s, bool is_white) {
        const double lo = level(*black_plane, s.x(), s.y()), hi = level(*white_plane, s.x(), s.y());
        if (hi - lo < min_contrast) contrasted = false;
        contrast_sum += hi - lo;
        ++count;
        const double m = ((is_white ? s.z() - (lo + hi) / 2 : (lo + hi) / 2 - s.z())) / std::max(hi - lo, 1e-9);
        worst = std::min(worst, m);
      };
      for (const Eigen::Vector3d& s : black) margin_of(s, false);
      for (const Eigen::Vector3d& s : white) margin_of(s, true);
      if (!contrasted) continue;  // white below black: a wrong winding, or no tag
      uint64_t code = 0;
      double bit_worst = 1e9;
      for (uint32_t i = 0; i < family->nbits && inside; ++i) {
        const Eigen::Vector2d p = project(tag_coord(family->bit_x[i]), tag_coord(family->bit_y[i]));
        const std::optional<double> v = SampleBilinear(g, p.x(), p.y());
        if (!v) {
          inside = false;
          break;
        }
        const double lo = level(*black_plane, p.x(), p.y()), hi = level(*white_plane, p.x(), p.y());
        bit_worst = std::min(bit_worst, std::abs(*v - (lo + hi) / 2) / std::max(hi - lo, 1e-9));
        code = (code << 1) | (*v > (lo + hi) / 2 ? 1u : 0u);
      }
      if (!inside) return std::nullopt;
      for (uint32_t c = 0; c < family->ncodes; ++c) {
        const int hamming = __builtin_popcountll(family->codes[c] ^ code);
        if (hamming > max_hamming) continue;
        QuadReading reading;
        reading.id = static_cast<TagId>(c);
        reading.hamming = hamming;
        reading.margin = std::min(worst, bit_worst);
        reading.contrast = contrast_sum / count;
        reading.corners = corners;
        if (!best || reading.hamming < best->hamming ||
            (reading.hamming == best->hamming && reading.margin > best->margin)) {
          best = reading;
        }
      }
    }
  }
  return best;
}

bool InsideQuad(const QuadCorners& quad, const Eigen::Vector2d& p) {
  std::vector<cv::Point2f> contour;
  for (const Eigen::Vector2d& c : quad) contour.emplace_back(static_cast<float>(c.x()), static_cast<float>(c.y()));
  return cv::pointPolygonTest(contour, cv::Point2f(static_cast<float>(p.x()), static_cast<float>(p.y())), false) >= 0;
}

}  // namespace tagsfm::detail
