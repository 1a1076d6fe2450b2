// preview.png: the targets and the camera path from above and from the side.
#include <algorithm>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "tagsfm/core/file_util.h"
#include "tagsfm/recon/result_writer.h"

namespace tagsfm {
namespace {

struct Panel {
  int axis_u, axis_v;  // world axes drawn across and up
  const char* title;
};

void DrawPanel(cv::Mat& canvas, const cv::Rect& area, const Panel& panel, const std::vector<Eigen::Vector3d>& targets,
               const std::vector<Eigen::Vector3d>& cameras) {
  double min_u = 1e300, max_u = -1e300, min_v = 1e300, max_v = -1e300;
  for (const auto* set : {&targets, &cameras}) {
    for (const auto& p : *set) {
      min_u = std::min(min_u, p[panel.axis_u]);
      max_u = std::max(max_u, p[panel.axis_u]);
      min_v = std::min(min_v, p[panel.axis_v]);
      max_v = std::max(max_v, p[panel.axis_v]);
    }
  }
  if (min_u > max_u) return;
  const double margin = 30;
  const double span = std::max({max_u - min_u, max_v - min_v, 1e-6});
  const double scale = std::min(area.width - 2 * margin, area.height - 2 * margin) / span;
  const auto to_px = [&](const Eigen::Vector3d& p) {
    return cv::Point(static_cast<int>(area.x + margin + (p[panel.axis_u] - min_u) * scale),
                     static_cast<int>(area.y + area.height - margin - (p[panel.axis_v] - min_v) * scale));
  };
  for (size_t i = 1; i < cameras.size(); ++i) cv::line(canvas, to_px(cameras[i - 1]), to_px(cameras[i]), {200, 120, 60}, 1, cv::LINE_AA);
  for (const auto& c : cameras) cv::circle(canvas, to_px(c), 2, {220, 80, 20}, cv::FILLED, cv::LINE_AA);
  for (const auto& t : targets) cv::circle(canvas, to_px(t), 2, {0, 140, 255}, cv::FILLED, cv::LINE_AA);
  cv::putText(canvas, panel.title, {area.x + 10, area.y + 20}, cv::FONT_HERSHEY_SIMPLEX, 0.5, {40, 40, 40}, 1, cv::LINE_AA);
  cv::rectangle(canvas, area, {180, 180, 180});
}

}  // namespace

Status WritePreview(const std::filesystem::path& path, const ReconstructionResult& result) {
  std::vector<Eigen::Vector3d> targets, cameras;
  for (const auto& [id, tag] : result.tags) {
    const TagCorners corners = tag.CornersInWorld();
    targets.insert(targets.end(), corners.begin(), corners.end());
  }
  for (const auto& f : result.frames) {
    if (f.registered) cameras.push_back(f.cam_from_world.ToRigid().Center());
  }
  cv::Mat canvas(480, 960, CV_8UC3, cv::Scalar(255, 255, 255));
  DrawPanel(canvas, {0, 0, 480, 480}, {0, 1, "top (x right, y up): targets orange, cameras blue"}, targets, cameras);
  DrawPanel(canvas, {480, 0, 480, 480}, {0, 2, "side (x right, z up)"}, targets, cameras);
  std::vector<unsigned char> png;
  if (!cv::imencode(".png", canvas, png)) return MakeError(path.string() + ": PNG encoding failed");
  return WriteFileAtomically(path, png);
}

}  // namespace tagsfm
