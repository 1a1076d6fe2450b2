#include "small_tag_reader.h"

#include <algorithm>
#include <cmath>
#include <utility>
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

namespace {

// Tag coordinates ((-1, 1), (1, 1), (1, -1), (-1, -1) at libapriltag's
// corners) to image pixels, and module indices to tag coordinates.
struct TagToImage {
  TagToImage(const QuadCorners& corners, int width_at_border) : w(width_at_border) {
    const std::vector<cv::Point2f> tag_pts{{-1, 1}, {1, 1}, {1, -1}, {-1, -1}};
    std::vector<cv::Point2f> image_pts(4);
    for (int i = 0; i < 4; ++i) {
      image_pts[i] = cv::Point2f(static_cast<float>(corners[i].x()), static_cast<float>(corners[i].y()));
    }
    h = cv::getPerspectiveTransform(tag_pts, image_pts);
  }
  // The centre of module (i, j); -1 and w are the white ring round the border.
  Eigen::Vector2d Module(double i, double j) const { return Project(Coord(i), Coord(j)); }
  Eigen::Vector2d Project(double tx, double ty) const {
    const cv::Vec3d v = h * cv::Vec3d(tx, ty, 1.0);
    return Eigen::Vector2d(v[0] / v[2], v[1] / v[2]);
  }
  double Coord(double module) const { return 2.0 * (module + 0.5) / w - 1.0; }

  int w;
  cv::Matx33d h;
};

// (x, y, grey) samples of the black border ring and of the white ring
// outside it (its corners left out); nullopt when one falls off the image.
struct BorderSamples {
  std::vector<Eigen::Vector3d> black, white;
};

std::optional<BorderSamples> SampleBorder(const cv::Mat& g, const TagToImage& tag) {
  const int w = tag.w;
  BorderSamples samples;
  for (int i = -1; i <= w; ++i) {
    for (int j = -1; j <= w; ++j) {
      const bool outer = i == -1 || j == -1 || i == w || j == w;
      const bool ring = !outer && (i == 0 || j == 0 || i == w - 1 || j == w - 1);
      if (!outer && !ring) continue;
      if (outer && (i == -1 || i == w) && (j == -1 || j == w)) continue;  // the white ring's corners
      const Eigen::Vector2d p = tag.Module(i, j);
      const std::optional<double> v = SampleBilinear(g, p.x(), p.y());
      if (!v) return std::nullopt;
      (outer ? samples.white : samples.black).emplace_back(p.x(), p.y(), *v);
    }
  }
  return samples;
}

// The black and white grey planes fitted to the border samples, and how
// clearly the samples sit on their side of the midway level.
struct BorderLevels {
  Eigen::Vector3d black_plane, white_plane;
  double worst_margin = 1e9;  // the least clear sample's distance from midway, over the contrast
  double mean_contrast = 0;
  bool contrasted = true;     // white above black by min_contrast everywhere
  double Low(double x, double y) const { return black_plane.x() + black_plane.y() * x + black_plane.z() * y; }
  double High(double x, double y) const { return white_plane.x() + white_plane.y() * x + white_plane.z() * y; }
};

std::optional<BorderLevels> FitBorderLevels(const BorderSamples& samples, double min_contrast) {
  const std::optional<Eigen::Vector3d> black_plane = FitGreyPlane(samples.black), white_plane = FitGreyPlane(samples.white);
  if (!black_plane || !white_plane) return std::nullopt;
  BorderLevels levels;
  levels.black_plane = *black_plane;
  levels.white_plane = *white_plane;
  double contrast_sum = 0.0;
  int count = 0;
  const auto margin_of = [&](const Eigen::Vector3d& s, bool is_white) {
    const double lo = levels.Low(s.x(), s.y()), hi = levels.High(s.x(), s.y());
    if (hi - lo < min_contrast) levels.contrasted = false;
    contrast_sum += hi - lo;
    ++count;
    const double m = ((is_white ? s.z() - (lo + hi) / 2 : (lo + hi) / 2 - s.z())) / std::max(hi - lo, 1e-9);
    levels.worst_margin = std::min(levels.worst_margin, m);
  };
  for (const Eigen::Vector3d& s : samples.black) margin_of(s, false);
  for (const Eigen::Vector3d& s : samples.white) margin_of(s, true);
  levels.mean_contrast = contrast_sum / count;
  return levels;
}

// The family's bits read against the border's levels: the code and the
// least clear bit's distance from midway over the contrast; nullopt when a
// bit falls off the image.
std::optional<std::pair<uint64_t, double>> ReadCode(const cv::Mat& g, const apriltag_family_t* family,
                                                    const TagToImage& tag, const BorderLevels& levels) {
  uint64_t code = 0;
  double bit_worst = 1e9;
  for (uint32_t i = 0; i < family->nbits; ++i) {
    const Eigen::Vector2d p = tag.Module(family->bit_x[i], family->bit_y[i]);
    const std::optional<double> v = SampleBilinear(g, p.x(), p.y());
    if (!v) return std::nullopt;
    const double lo = levels.Low(p.x(), p.y()), hi = levels.High(p.x(), p.y());
    bit_worst = std::min(bit_worst, std::abs(*v - (lo + hi) / 2) / std::max(hi - lo, 1e-9));
    code = (code << 1) | (*v > (lo + hi) / 2 ? 1u : 0u);
  }
  return std::make_pair(code, bit_worst);
}

}  // namespace

std::optional<QuadReading> ReadQuad(const cv::Mat& g, const apriltag_family_t* family, const QuadCorners& q,
                                    int max_hamming, double min_contrast) {
  std::optional<QuadReading> best;
  for (int winding = 0; winding < 2; ++winding) {
    for (int start = 0; start < 4; ++start) {
      QuadCorners corners;
      for (int i = 0; i < 4; ++i) corners[i] = q[winding ? (4 - i + start) % 4 : (i + start) % 4];
      const TagToImage tag(corners, family->width_at_border);
      const std::optional<BorderSamples> samples = SampleBorder(g, tag);
      if (!samples) return std::nullopt;  // the same samples for every order
      const std::optional<BorderLevels> levels = FitBorderLevels(*samples, min_contrast);
      if (!levels) return std::nullopt;
      if (!levels->contrasted) continue;  // white below black: a wrong winding, or no tag
      const auto code = ReadCode(g, family, tag, *levels);
      if (!code) return std::nullopt;
      for (uint32_t c = 0; c < family->ncodes; ++c) {
        const int hamming = __builtin_popcountll(family->codes[c] ^ code->first);
        if (hamming > max_hamming) continue;
        QuadReading reading;
        reading.id = static_cast<TagId>(c);
        reading.hamming = hamming;
        reading.margin = std::min(levels->worst_margin, code->second);
        reading.contrast = levels->mean_contrast;
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
