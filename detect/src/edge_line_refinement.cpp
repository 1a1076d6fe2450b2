// Corner refinement by fitting the four outer edges of the tag's square.
//
// Why edges rather than corners: a corner's position is decided by a few
// pixels around it, an edge line by every pixel along it, so averaging over
// ~20 profiles per edge divides the noise by ~4, and a blurred step's
// gradient centroid is an unbiased estimate of the edge position whatever the
// (symmetric) blur, as long as the window is symmetric about the edge: hence
// the re-centring iterations.
#include <algorithm>
#include <cmath>
#include <vector>

#include <Eigen/Eigenvalues>

#include "tagsfm/detect/corner_refinement.h"

namespace tagsfm {
namespace {

// Bilinear interpolation, pixel centres at integers; false outside the image.
bool SampleBilinear(const cv::Mat& image, double x, double y, double* value) {
  if (!(x >= 0.0 && y >= 0.0 && x <= image.cols - 1.0 && y <= image.rows - 1.0)) return false;
  const int x0 = std::min(static_cast<int>(x), image.cols - 2 < 0 ? 0 : image.cols - 2);
  const int y0 = std::min(static_cast<int>(y), image.rows - 2 < 0 ? 0 : image.rows - 2);
  const double fx = x - x0;
  const double fy = y - y0;
  const int x1 = std::min(x0 + 1, image.cols - 1);
  const int y1 = std::min(y0 + 1, image.rows - 1);
  const uchar* row0 = image.ptr<uchar>(y0);
  const uchar* row1 = image.ptr<uchar>(y1);
  const double top = row0[x0] + fx * (row0[x1] - row0[x0]);
  const double bottom = row1[x0] + fx * (row1[x1] - row1[x0]);
  *value = top + fy * (bottom - top);
  return true;
}

struct EdgePoint {
  Eigen::Vector2d position;
  double weight = 0.0;
};

// Weighted total-least-squares line through the points; normal oriented like
// `normal_hint`.
bool FitLine(const std::vector<EdgePoint>& points, const Eigen::Vector2d& normal_hint, EdgeLine* line) {
  double weight_sum = 0.0;
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  for (const EdgePoint& p : points) {
    weight_sum += p.weight;
    mean += p.weight * p.position;
  }
  if (points.size() < 3 || !(weight_sum > 0.0)) return false;
  mean /= weight_sum;
  Eigen::Matrix2d scatter = Eigen::Matrix2d::Zero();
  for (const EdgePoint& p : points) {
    const Eigen::Vector2d d = p.position - mean;
    scatter += p.weight * d * d.transpose();
  }
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> solver(scatter);
  Eigen::Vector2d normal = solver.eigenvectors().col(0);  // smallest eigenvalue: across the line
  if (normal.dot(normal_hint) < 0.0) normal = -normal;
  line->normal = normal;
  line->offset = normal.dot(mean);
  return true;
}

struct EdgeFitSettings {
  double half_window_px;  // profile half-length across the edge
  double step_px = 0.25;  // profile sampling step
  double end_margin_px;   // stay this far from the corners along the edge
  int max_profiles = 64;  // profiles per edge (caps the cost on large tags)
  int iterations = 3;
};

// Sub-pixel edge positions along `profiles` normals to the current line.
// polarity +1: brighter outside (a black square on white), -1: the reverse,
// 0: either (used once, to find out which).
struct ProfileScan {
  std::vector<EdgePoint> points;
  double signed_gradient_sum = 0.0;
};

ProfileScan ScanProfiles(const cv::Mat& image, const Eigen::Vector2d& from, const Eigen::Vector2d& along,
                         double usable, int profiles, const EdgeFitSettings& settings, const EdgeLine& line,
                         double polarity) {
  const int samples = static_cast<int>(std::lround(2.0 * settings.half_window_px / settings.step_px)) + 1;
  std::vector<double> profile(samples);
  ProfileScan scan;
  scan.points.reserve(profiles);
  for (int j = 0; j < profiles; ++j) {
    const double t = settings.end_margin_px + usable * (j + 0.5) / profiles;
    Eigen::Vector2d base = from + t * along;
    base -= (line.normal.dot(base) - line.offset) * line.normal;  // onto the current line
    bool inside = true;
    for (int k = 0; k < samples && inside; ++k) {
      const Eigen::Vector2d p = base + (-settings.half_window_px + k * settings.step_px) * line.normal;
      inside = SampleBilinear(image, p.x(), p.y(), &profile[k]);
    }
    if (!inside) continue;
    double moment = 0.0;
    double mass = 0.0;
    for (int k = 1; k + 1 < samples; ++k) {
      const double gradient = profile[k + 1] - profile[k - 1];
      scan.signed_gradient_sum += gradient;
      // Only the expected polarity: opposite-signed edges nearby (the
      // border's inner edge, a dark background) must not pull the centroid.
      const double g = polarity == 0.0 ? std::abs(gradient) : std::max(0.0, polarity * gradient);
      moment += g * (-settings.half_window_px + k * settings.step_px);
      mass += g;
    }
    if (mass <= 0.0) continue;
    scan.points.push_back({base + (moment / mass) * line.normal, mass});
  }
  return scan;
}

// Fits one edge from `from` to `to`, starting from `line`.
bool FitEdge(const cv::Mat& image, const Eigen::Vector2d& from, const Eigen::Vector2d& to,
             const EdgeFitSettings& settings, EdgeLine* line) {
  const double length = (to - from).norm();
  const double usable = length - 2.0 * settings.end_margin_px;
  if (!(usable > 2.0)) return false;
  const int profiles = std::clamp(static_cast<int>(usable), 4, settings.max_profiles);
  const Eigen::Vector2d along = (to - from) / length;

  const ProfileScan first = ScanProfiles(image, from, along, usable, profiles, settings, *line, 0.0);
  if (first.points.size() < 3) return false;
  const double polarity = first.signed_gradient_sum >= 0.0 ? 1.0 : -1.0;
  for (int iteration = 0; iteration < settings.iterations; ++iteration) {
    const ProfileScan scan = ScanProfiles(image, from, along, usable, profiles, settings, *line, polarity);
    if (scan.points.size() < 3) return false;
    EdgeLine fitted = *line;
    if (!FitLine(scan.points, line->normal, &fitted)) return false;
    // Drop profiles hit by something else (a specular spot, an occluder).
    std::vector<double> residuals;
    for (const EdgePoint& p : scan.points) residuals.push_back(std::abs(fitted.normal.dot(p.position) - fitted.offset));
    std::vector<double> sorted = residuals;
    std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
    const double limit = std::max(0.1, 4.0 * 1.4826 * sorted[sorted.size() / 2]);
    std::vector<EdgePoint> kept;
    for (size_t i = 0; i < scan.points.size(); ++i) {
      if (residuals[i] <= limit) kept.push_back(scan.points[i]);
    }
    if (!FitLine(kept, line->normal, &fitted)) return false;
    *line = fitted;
  }
  return true;
}

bool Intersect(const EdgeLine& a, const EdgeLine& b, Eigen::Vector2d* point) {
  Eigen::Matrix2d normals;
  normals << a.normal.transpose(), b.normal.transpose();
  const double det = normals.determinant();
  if (std::abs(det) < 1e-3) return false;  // nearly parallel edges: no reliable corner
  *point = normals.inverse() * Eigen::Vector2d(a.offset, b.offset);
  return true;
}

}  // namespace

bool RefineCornersByEdgeLines(const cv::Mat& gray8, int modules_across, QuadCorners* corners) {
  if (gray8.empty() || gray8.type() != CV_8UC1 || modules_across <= 0) return false;
  const QuadCorners initial = *corners;
  const Eigen::Vector2d center = 0.25 * (initial[0] + initial[1] + initial[2] + initial[3]);
  double mean_side = 0.0;
  for (int i = 0; i < 4; ++i) mean_side += 0.25 * (initial[(i + 1) % 4] - initial[i]).norm();
  const double module_px = mean_side / modules_across;

  EdgeFitSettings settings;
  // Inside a one-module black border, outside at least a one-module white
  // margin: a window of 0.8 module keeps other edges out but the blurred step in.
  settings.half_window_px = std::clamp(0.8 * module_px, 1.25, 8.0);
  // The adjacent edge's blur reaches ~2 px (plus the start's error) along this one.
  settings.end_margin_px = std::max(2.5, 0.08 * mean_side);

  std::array<EdgeLine, 4> lines;  // edge i runs from corner i to corner i+1
  for (int i = 0; i < 4; ++i) {
    const Eigen::Vector2d& from = initial[i];
    const Eigen::Vector2d& to = initial[(i + 1) % 4];
    const Eigen::Vector2d along = (to - from).normalized();
    Eigen::Vector2d normal(-along.y(), along.x());
    if (normal.dot(0.5 * (from + to) - center) < 0.0) normal = -normal;
    lines[i].normal = normal;
    lines[i].offset = normal.dot(from);
    if (!FitEdge(gray8, from, to, settings, &lines[i])) return false;
  }
  QuadCorners refined;
  for (int i = 0; i < 4; ++i) {
    if (!Intersect(lines[(i + 3) % 4], lines[i], &refined[i])) return false;
  }
  // A refinement that moves a corner by more than half a module has locked
  // onto something else; the start is then the better answer.
  const double max_move = std::max(1.5, 0.5 * module_px);
  for (int i = 0; i < 4; ++i) {
    if (!((refined[i] - initial[i]).norm() <= max_move)) return false;
  }
  *corners = refined;
  return true;
}

}  // namespace tagsfm
