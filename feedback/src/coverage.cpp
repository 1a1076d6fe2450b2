#include "tagsfm/feedback/coverage.h"

#include <cmath>
#include <limits>
#include <optional>

#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>


namespace tagsfm {
namespace {

constexpr double kRadToDeg = 180.0 / M_PI;
// Directions kept per target for the spread: enough to find the widest pair
// without growing with the length of the capture.
constexpr size_t kMaxKeptDirections = 16;

double AngleDeg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::atan2(a.cross(b).norm(), a.dot(b)) * kRadToDeg;
}

// IPPE's two solutions (the planar ambiguity) are first-order
// approximations: unrefined, the wrong one of a nearly head-on tag can
// reproject better than the right one (measured on exact data with OpenCV
// 4.6). Both are refined with LM, in pixel units so that its convergence
// thresholds mean what they say, and the better one is kept. The tag frame is
// first turned 180 degrees about x: a tag facing the camera is then near the
// identity rotation, far from the rotation vector's singularity at 180
// degrees, where LM was seen to wander off an exact start.
std::optional<Rigid3d> BestTagPose(const std::array<Eigen::Vector2d, 4>& normalized, double size_m, double focal_px) {
  const double h = 0.5 * size_m;
  // Corners in the turned frame: (x, y, 0) -> (x, -y, 0).
  const std::vector<cv::Point3d> corners_in_tag{{-h, h, 0}, {h, h, 0}, {h, -h, 0}, {-h, -h, 0}};
  const Eigen::Quaterniond turned_from_tag(Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitX()));
  std::vector<cv::Point2d> observed;
  for (const auto& n : normalized) observed.emplace_back(focal_px * n.x(), focal_px * n.y());
  const cv::Matx33d K(focal_px, 0, 0, 0, focal_px, 0, 0, 0, 1);
  std::vector<cv::Mat> rvecs, tvecs;
  try {
    cv::solvePnPGeneric(corners_in_tag, observed, K, cv::noArray(), rvecs, tvecs, false, cv::SOLVEPNP_IPPE);
  } catch (const cv::Exception&) {
    return std::nullopt;  // degenerate corners (e.g. collapsed to a line)
  }
  std::optional<Rigid3d> best;
  double best_error = 0;
  for (size_t i = 0; i < rvecs.size(); ++i) {
    cv::solvePnPRefineLM(corners_in_tag, observed, K, cv::noArray(), rvecs[i], tvecs[i]);
    std::vector<cv::Point2d> projected;
    cv::projectPoints(corners_in_tag, rvecs[i], tvecs[i], K, cv::noArray(), projected);
    double error = 0;
    for (int k = 0; k < 4; ++k) error += cv::norm(projected[k] - observed[k]);
    cv::Mat rotation;
    cv::Rodrigues(rvecs[i], rotation);
    Eigen::Matrix3d r;
    Eigen::Vector3d t;
    cv::cv2eigen(rotation, r);
    cv::cv2eigen(tvecs[i], t);
    if (!(t.z() > 0) || !t.allFinite()) continue;
    if (!best || error < best_error) {
      best = Rigid3d(Eigen::Quaterniond(r) * turned_from_tag, t);
      best_error = error;
    }
  }
  return best;
}

}  // namespace

int TargetCoverage::SectorsCovered() const {
  int covered = 0;
  for (int views : sector_views) covered += views > 0 ? 1 : 0;
  return covered;
}

std::vector<TagView> ComputeTagViews(const CameraModel& camera, const TargetConfig& targets,
                                     const DetectionSet& detections) {
  std::vector<TagView> views;
  views.reserve(detections.tags.size());
  std::vector<Eigen::Vector2d> pixels;
  for (const auto& tag : detections.tags) pixels.insert(pixels.end(), tag.corners.begin(), tag.corners.end());
  const std::vector<Eigen::Vector2d> normalized = camera.PixelsToNormalized(pixels);
  for (size_t i = 0; i < detections.tags.size(); ++i) {
    const TagDetection& tag = detections.tags[i];
    const std::array<Eigen::Vector2d, 4> corners{normalized[4 * i], normalized[4 * i + 1], normalized[4 * i + 2],
                                                 normalized[4 * i + 3]};
    const auto cam_from_tag = BestTagPose(corners, targets.SizeOf(tag.id), 0.5 * (camera.fx + camera.fy));
    if (!cam_from_tag) continue;
    const Rigid3d tag_from_cam = cam_from_tag->Inverse();
    const Eigen::Vector3d camera_in_tag = tag_from_cam.translation;
    TagView view;
    view.id = tag.id;
    view.distance_m = camera_in_tag.norm();
    if (!(view.distance_m > 0)) continue;
    view.camera_direction_in_tag = camera_in_tag / view.distance_m;
    // The tag's normal is its z axis; the camera sits on the side it faces,
    // whichever sign libapriltag's frame gives that side.
    view.tilt_deg = std::acos(std::min(1.0, std::abs(view.camera_direction_in_tag.z()))) * kRadToDeg;
    views.push_back(view);
  }
  return views;
}

void CoverageTracker::Add(FrameId frame, const std::vector<TagView>& views) {
  for (const TagView& view : views) {
    TargetCoverage& c = targets_[view.id];
    c.id = view.id;
    ++c.times_seen;
    c.last_seen = frame;
    c.last_distance_m = view.distance_m;
    c.min_tilt_deg = std::min(c.min_tilt_deg, view.tilt_deg);
    c.max_tilt_deg = std::max(c.max_tilt_deg, view.tilt_deg);
    if (view.tilt_deg >= kMinTiltForSectorDeg) {
      const Eigen::Vector3d& d = view.camera_direction_in_tag;
      const double azimuth = std::atan2(d.y(), d.x()) * kRadToDeg + 180.0;  // 0..360
      const int sector = std::min(kCoverageSectors - 1, static_cast<int>(azimuth / (360.0 / kCoverageSectors)));
      ++c.sector_views[sector];
    }
    // Keep a direction only when it widens what is known, so the kept set
    // stays small and the spread is exact for the directions kept.
    double widest_new = 0;
    for (const auto& kept : c.directions_in_tag) widest_new = std::max(widest_new, AngleDeg(kept, view.camera_direction_in_tag));
    if (c.directions_in_tag.empty() || (widest_new > c.direction_spread_deg && c.directions_in_tag.size() < kMaxKeptDirections)) {
      c.directions_in_tag.push_back(view.camera_direction_in_tag);
    }
    c.direction_spread_deg = std::max(c.direction_spread_deg, widest_new);
  }
}

}  // namespace tagsfm
