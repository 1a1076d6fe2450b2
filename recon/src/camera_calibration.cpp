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

Result<CalibrationResult> CalibrateFromTargets(const std::vector<DetectionSet>& detections,
                                               const TargetConfig& targets, int width, int height,
                                               const std::optional<TargetCornerMap>& known_map,
                                               const CalibrationOptions& options) {
  if (Status s = options.Check(); !s) return s.error();
  if (width <= 0 || height <= 0) return MakeError("calibration: image size unknown");
  // Every sufficiently large tag view is one planar object of 4 points.
  std::vector<std::vector<cv::Point3f>> object_points;
  std::vector<std::vector<cv::Point2f>> image_points;
  std::vector<int> frame_of_view;
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
      object_points.push_back(std::move(object));
      image_points.push_back(std::move(image));
      frame_of_view.push_back(static_cast<int>(f));
    }
  }
  if (object_points.size() < 3) {
    return MakeError("calibration: only " + std::to_string(object_points.size()) +
                     " tag views of at least " + std::to_string(static_cast<int>(options.min_tag_side_px)) +
                     " px; need 3 or more, seen from different angles");
  }
  if (object_points.size() > static_cast<size_t>(options.max_views)) {
    std::vector<std::vector<cv::Point3f>> o;
    std::vector<std::vector<cv::Point2f>> i;
    std::vector<int> fr;
    const double step = static_cast<double>(object_points.size()) / options.max_views;
    for (int k = 0; k < options.max_views; ++k) {
      const size_t idx = static_cast<size_t>(k * step);
      o.push_back(object_points[idx]);
      i.push_back(image_points[idx]);
      fr.push_back(frame_of_view[idx]);
    }
    object_points.swap(o);
    image_points.swap(i);
    frame_of_view.swap(fr);
  }
  int flags = 0;
  if (!options.estimate_k3) flags |= cv::CALIB_FIX_K3;
  if (!options.estimate_tangential) flags |= cv::CALIB_ZERO_TANGENT_DIST;
  cv::Mat k, dist;
  std::vector<cv::Mat> rvecs, tvecs;
  double rms = 0;
  try {
    rms = cv::calibrateCamera(object_points, image_points, cv::Size(width, height), k, dist, rvecs, tvecs, flags);
  } catch (const cv::Exception& e) {
    return MakeError(std::string("calibration failed: ") + e.what());
  }
  CalibrationResult out;
  // With a known map, whole frames of map corners (non-planar) refine it.
  if (known_map && !known_map->empty()) {
    std::vector<std::vector<cv::Point3f>> map_object;
    std::vector<std::vector<cv::Point2f>> map_image;
    for (const auto& set : detections) {
      std::vector<cv::Point3f> o;
      std::vector<cv::Point2f> i;
      for (const auto& tag : set.tags) {
        auto it = known_map->find(tag.id);
        if (it == known_map->end()) continue;
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
    if (map_object.size() >= 3) {
      cv::Mat k2 = k.clone(), d2 = dist.clone();
      try {
        const double rms2 = cv::calibrateCamera(map_object, map_image, cv::Size(width, height), k2, d2, rvecs, tvecs,
                                                flags | cv::CALIB_USE_INTRINSIC_GUESS);
        if (std::isfinite(rms2) && rms2 < 2.0) {
          k = k2;
          dist = d2;
          rms = rms2;
        }
      } catch (const cv::Exception&) {
        // Keep the per-tag estimate.
      }
    }
  }
  out.camera.width = width;
  out.camera.height = height;
  out.camera.fx = k.at<double>(0, 0);
  out.camera.fy = k.at<double>(1, 1);
  out.camera.cx = k.at<double>(0, 2);
  out.camera.cy = k.at<double>(1, 2);
  out.camera.distortion.assign(dist.begin<double>(), dist.end<double>());
  if (out.camera.distortion.size() > 5) out.camera.distortion.resize(5);
  out.rms_px = rms;
  out.views = static_cast<int>(object_points.size());
  std::vector<int> frames(frame_of_view);
  std::sort(frames.begin(), frames.end());
  out.frames = static_cast<int>(std::unique(frames.begin(), frames.end()) - frames.begin());
  if (Status s = out.camera.Check(); !s) return MakeError("calibration gave an invalid camera: " + s.error().message);
  return out;
}

}  // namespace tagsfm
