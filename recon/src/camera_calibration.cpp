#include "tagsfm/recon/camera_calibration.h"

#include <cmath>

#include <opencv2/calib3d.hpp>

#include "tagsfm/recon/tag_geometry.h"

namespace tagsfm {

Status CalibrationOptions::Check() const {
  if (max_views < 3) return MakeError("calibration.max_views must be >= 3");
  if (!(min_tag_side_px >= 0)) return MakeError("calibration.min_tag_side_px must be >= 0");
  return Status::Ok();
}

namespace {

// Every tag view large enough, as one planar object of 4 points.
struct PlanarViews {
  std::vector<std::vector<cv::Point3f>> object_points;
  std::vector<std::vector<cv::Point2f>> image_points;
  std::vector<int> frame_of_view;
};

PlanarViews TagViews(const std::vector<DetectionSet>& detections, const TargetConfig& targets,
                     const CalibrationOptions& options) {
  PlanarViews views;
  for (size_t f = 0; f < detections.size(); ++f) {
    for (const auto& tag : detections[f].tags) {
      const double size = targets.SizeOf(tag.id);
      if (!(size > 0)) continue;
      double min_side = 1e300;
      for (int k = 0; k < 4; ++k) min_side = std::min(min_side, (tag.corners[(k + 1) % 4] - tag.corners[k]).norm());
      if (min_side < options.min_tag_side_px) continue;
      std::vector<cv::Point3f> object;
      std::vector<cv::Point2f> image;
      for (int k = 0; k < 4; ++k) {
        const Eigen::Vector3d c = TagCornerInTag(k, size);
        object.emplace_back(static_cast<float>(c.x()), static_cast<float>(c.y()), 0.0f);
        image.emplace_back(static_cast<float>(tag.corners[k].x()), static_cast<float>(tag.corners[k].y()));
      }
      views.object_points.push_back(std::move(object));
      views.image_points.push_back(std::move(image));
      views.frame_of_view.push_back(static_cast<int>(f));
    }
  }
  return views;
}

// At most `max_views` of the views, evenly spread over the sequence.
void KeepEvenly(PlanarViews* views, int max_views) {
  if (views->object_points.size() <= static_cast<size_t>(max_views)) return;
  PlanarViews kept;
  const double step = static_cast<double>(views->object_points.size()) / max_views;
  for (int k = 0; k < max_views; ++k) {
    const size_t idx = static_cast<size_t>(k * step);
    kept.object_points.push_back(views->object_points[idx]);
    kept.image_points.push_back(views->image_points[idx]);
    kept.frame_of_view.push_back(views->frame_of_view[idx]);
  }
  *views = std::move(kept);
}

// With a known map, whole frames of map corners (non-planar) refine the
// per-tag estimate `k`, `dist`, `rms`, which are kept when that fails.
// `rvecs` and `tvecs` are the per-tag solve's, reused as OpenCV's output
// buffers (fresh ones change the result in the 14th digit).
void RefineWithKnownMap(const std::vector<DetectionSet>& detections, const TargetCornerMap& known_map, cv::Size size,
                        int flags, cv::Mat* k, cv::Mat* dist, double* rms, std::vector<cv::Mat>* rvecs,
                        std::vector<cv::Mat>* tvecs) {
  std::vector<std::vector<cv::Point3f>> map_object;
  std::vector<std::vector<cv::Point2f>> map_image;
  for (const auto& set : detections) {
    std::vector<cv::Point3f> o;
    std::vector<cv::Point2f> i;
    for (const auto& tag : set.tags) {
      auto it = known_map.find(tag.id);
      if (it == known_map.end()) continue;
      for (int c = 0; c < 4; ++c) {
        o.emplace_back(static_cast<float>(it->second[c].x()), static_cast<float>(it->second[c].y()),
                       static_cast<float>(it->second[c].z()));
        i.emplace_back(static_cast<float>(tag.corners[c].x()), static_cast<float>(tag.corners[c].y()));
      }
    }
    if (o.size() >= 12) {
      map_object.push_back(std::move(o));
      map_image.push_back(std::move(i));
    }
  }
  if (map_object.size() < 3) return;
  cv::Mat k2 = k->clone(), d2 = dist->clone();
  try {
    const double rms2 =
        cv::calibrateCamera(map_object, map_image, size, k2, d2, *rvecs, *tvecs, flags | cv::CALIB_USE_INTRINSIC_GUESS);
    if (std::isfinite(rms2) && rms2 < 2.0) {
      *k = k2;
      *dist = d2;
      *rms = rms2;
    }
  } catch (const cv::Exception&) {
    // Keep the per-tag estimate.
  }
}

CameraModel CameraFrom(const cv::Mat& k, const cv::Mat& dist, int width, int height) {
  CameraModel camera;
  camera.width = width;
  camera.height = height;
  camera.fx = k.at<double>(0, 0);
  camera.fy = k.at<double>(1, 1);
  camera.cx = k.at<double>(0, 2);
  camera.cy = k.at<double>(1, 2);
  camera.distortion.assign(dist.begin<double>(), dist.end<double>());
  if (camera.distortion.size() > 5) camera.distortion.resize(5);
  return camera;
}

}  // namespace

Result<CalibrationResult> CalibrateFromTargets(const std::vector<DetectionSet>& detections,
                                               const TargetConfig& targets, int width, int height,
                                               const std::optional<TargetCornerMap>& known_map,
                                               const CalibrationOptions& options) {
  if (Status s = options.Check(); !s) return s.error();
  if (width <= 0 || height <= 0) return MakeError("calibration: image size unknown");
  PlanarViews views = TagViews(detections, targets, options);
  if (views.object_points.size() < 3) {
    return MakeError("calibration: only " + std::to_string(views.object_points.size()) +
                     " tag views of at least " + std::to_string(static_cast<int>(options.min_tag_side_px)) +
                     " px; need 3 or more, seen from different angles");
  }
  KeepEvenly(&views, options.max_views);
  int flags = 0;
  if (!options.estimate_k3) flags |= cv::CALIB_FIX_K3;
  if (!options.estimate_tangential) flags |= cv::CALIB_ZERO_TANGENT_DIST;
  cv::Mat k, dist;
  std::vector<cv::Mat> rvecs, tvecs;
  double rms = 0;
  try {
    rms = cv::calibrateCamera(views.object_points, views.image_points, cv::Size(width, height), k, dist, rvecs, tvecs,
                              flags);
  } catch (const cv::Exception& e) {
    return MakeError(std::string("calibration failed: ") + e.what());
  }
  if (known_map && !known_map->empty()) {
    RefineWithKnownMap(detections, *known_map, cv::Size(width, height), flags, &k, &dist, &rms, &rvecs, &tvecs);
  }
  CalibrationResult out;
  out.camera = CameraFrom(k, dist, width, height);
  out.rms_px = rms;
  out.views = static_cast<int>(views.object_points.size());
  std::vector<int> frames(views.frame_of_view);
  std::sort(frames.begin(), frames.end());
  out.frames = static_cast<int>(std::unique(frames.begin(), frames.end()) - frames.begin());
  if (Status s = out.camera.Check(); !s) return MakeError("calibration gave an invalid camera: " + s.error().message);
  return out;
}

}  // namespace tagsfm
