// preview.png: the cloud (targets and feature points) and the camera path,
// from above and from the side. "Above" is along the points' direction of
// least spread (principal axes of the targets and features), not a world
// axis: without a known map the world frame is the anchor tag's, which may
// hang on a wall.
#include <algorithm>

#include <Eigen/Eigenvalues>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "tagsfm/core/file_util.h"
#include "tagsfm/export/result_writer.h"

namespace tagsfm {
namespace {

struct Panel {
  int axis_u, axis_v;  // principal axes drawn across and up
  const char* title;
};

struct ColouredPoint {
  Eigen::Vector3d p;
  cv::Scalar bgr;
};

// Robust bounds of the points: the 1st to 99th percentile, so that a few
// stray feature points do not shrink the drawing.
std::pair<double, double> Bounds(std::vector<double> values) {
  if (values.empty()) return {0, 0};
  std::sort(values.begin(), values.end());
  const size_t lo = values.size() / 100, hi = values.size() - 1 - values.size() / 100;
  return {values[lo], values[hi]};
}

void DrawPanel(cv::Mat& canvas, const cv::Rect& area, const Panel& panel, const std::vector<ColouredPoint>& points,
               const std::vector<Eigen::Vector3d>& cameras) {
  std::vector<double> us, vs;
  for (const auto& c : points) {
    us.push_back(c.p[panel.axis_u]);
    vs.push_back(c.p[panel.axis_v]);
  }
  if (us.empty() && cameras.empty()) return;
  auto [min_u, max_u] = us.empty() ? std::pair{1e300, -1e300} : Bounds(us);
  auto [min_v, max_v] = vs.empty() ? std::pair{1e300, -1e300} : Bounds(vs);
  for (const auto& c : cameras) {  // the whole camera path, always
    min_u = std::min(min_u, c[panel.axis_u]);
    max_u = std::max(max_u, c[panel.axis_u]);
    min_v = std::min(min_v, c[panel.axis_v]);
    max_v = std::max(max_v, c[panel.axis_v]);
  }
  const double margin = 30;
  const double span = std::max({max_u - min_u, max_v - min_v, 1e-6});
  const double scale = std::min(area.width - 2 * margin, area.height - 2 * margin) / span;
  // Plain copies: clang 14 cannot capture a structured binding.
  const double u0 = min_u, v0 = min_v;
  const auto to_px = [&](const Eigen::Vector3d& p) {
    return cv::Point(static_cast<int>(area.x + margin + (p[panel.axis_u] - u0) * scale),
                     static_cast<int>(area.y + area.height - margin - (p[panel.axis_v] - v0) * scale));
  };
  cv::Mat view = canvas(area);
  const cv::Point offset(area.x, area.y);
  for (const auto& c : points) {
    const cv::Point q = to_px(c.p) - offset;
    if (q.inside(cv::Rect(0, 0, area.width, area.height))) view.at<cv::Vec3b>(q) = cv::Vec3b(c.bgr[0], c.bgr[1], c.bgr[2]);
  }
  for (size_t i = 1; i < cameras.size(); ++i) cv::line(canvas, to_px(cameras[i - 1]), to_px(cameras[i]), {200, 120, 60}, 1, cv::LINE_AA);
  for (const auto& c : cameras) cv::circle(canvas, to_px(c), 2, {220, 80, 20}, cv::FILLED, cv::LINE_AA);
  for (const auto& c : points) {
    if (c.bgr == cv::Scalar(0, 140, 255)) cv::circle(canvas, to_px(c.p), 2, c.bgr, cv::FILLED, cv::LINE_AA);
  }
  cv::putText(canvas, panel.title, {area.x + 10, area.y + 20}, cv::FONT_HERSHEY_SIMPLEX, 0.5, {40, 40, 40}, 1, cv::LINE_AA);
  cv::rectangle(canvas, area, {180, 180, 180});
}

}  // namespace

Status WritePreview(const std::filesystem::path& path, const ReconstructionResult& result) {
  std::vector<ColouredPoint> points;
  for (const auto& [id, tag] : result.tags) {
    for (const Eigen::Vector3d& corner : tag.CornersInWorld()) points.push_back({corner, {0, 140, 255}});
  }
  for (const FeaturePoint& f : result.feature_points) {
    // Features in their own colour, darkened so that white ones show.
    points.push_back({f.position, cv::Scalar(0.7 * f.rgb[2], 0.7 * f.rgb[1], 0.7 * f.rgb[0])});
  }
  std::vector<Eigen::Vector3d> cameras;
  for (const auto& f : result.frames) {
    if (f.registered) cameras.push_back(f.cam_from_world.ToRigid().Center());
  }
  // Principal axes of the points (cameras when there are none), largest
  // first: axes 0 and 1 span the scene's main plane, 2 is its normal.
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
  std::vector<Eigen::Vector3d> basis_points;
  for (const auto& c : points) basis_points.push_back(c.p);
  if (basis_points.size() < 3) basis_points = cameras;
  for (const auto& p : basis_points) mean += p / static_cast<double>(basis_points.size());
  for (const auto& p : basis_points) scatter += (p - mean) * (p - mean).transpose();
  Eigen::Matrix3d axes = Eigen::Matrix3d::Identity();
  if (basis_points.size() >= 3) {
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(scatter);
    axes = eigen.eigenvectors().rowwise().reverse().transpose();  // rows: largest spread first
    if (axes.determinant() < 0) axes.row(2) *= -1;
  }
  // The normal points towards the cameras, so that "up" in the side view is
  // the side the cameras were on.
  if (!cameras.empty() && axes.row(2).dot(cameras.front() - mean) < 0) {
    axes.row(2) *= -1;
    axes.row(1) *= -1;
  }
  for (auto& c : points) c.p = axes * (c.p - mean);
  for (auto& c : cameras) c = axes * (c - mean);

  cv::Mat canvas(480, 960, CV_8UC3, cv::Scalar(255, 255, 255));
  DrawPanel(canvas, {0, 0, 480, 480}, {0, 1, "top: targets orange, features, cameras blue"}, points, cameras);
  DrawPanel(canvas, {480, 0, 480, 480}, {0, 2, "side"}, points, cameras);
  std::vector<unsigned char> png;
  if (!cv::imencode(".png", canvas, png)) return MakeError(path.string() + ": PNG encoding failed");
  return WriteFileAtomically(path, png);
}

}  // namespace tagsfm
