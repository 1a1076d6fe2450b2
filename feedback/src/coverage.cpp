#include "tagsfm/feedback/coverage.h"

#include <cmath>
#include <vector>

#include "tagsfm/recon/pose_estimator.h"

namespace tagsfm {
namespace {

constexpr double kRadToDeg = 180.0 / M_PI;
// Directions kept per target for the spread: enough to find the widest pair
// without growing with the length of the capture.
constexpr size_t kMaxKeptDirections = 16;

double AngleDeg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::atan2(a.cross(b).norm(), a.dot(b)) * kRadToDeg;
}

}  // namespace

int TargetCoverage::SectorsCovered() const {
  int covered = 0;
  for (int views : sector_views) covered += views > 0 ? 1 : 0;
  return covered;
}

std::vector<TagSighting> ComputeTagViews(const CameraModel& camera, const TargetConfig& targets,
                                     const DetectionSet& detections) {
  std::vector<TagSighting> views;
  views.reserve(detections.tags.size());
  std::vector<Eigen::Vector2d> pixels;
  for (const auto& tag : detections.tags) pixels.insert(pixels.end(), tag.corners.begin(), tag.corners.end());
  const std::vector<Eigen::Vector2d> normalized = camera.PixelsToNormalized(pixels);
  for (size_t i = 0; i < detections.tags.size(); ++i) {
    const TagDetection& tag = detections.tags[i];
    const std::array<Eigen::Vector2d, 4> corners{normalized[4 * i], normalized[4 * i + 1], normalized[4 * i + 2],
                                                 normalized[4 * i + 3]};
    // recon's IPPE pair, both branches refined and ranked, best first.
    const std::vector<Rigid3d> candidates = TagPoseCandidates(corners, targets.SizeOf(tag.id));
    if (candidates.empty()) continue;
    const Rigid3d tag_from_cam = candidates.front().Inverse();
    const Eigen::Vector3d camera_in_tag = tag_from_cam.translation;
    TagSighting view;
    view.id = tag.id;
    view.distance_m = camera_in_tag.norm();
    if (!(view.distance_m > 0)) continue;
    view.camera_direction_in_tag = camera_in_tag / view.distance_m;
    view.centre_in_cam = candidates.front().translation;
    // The tag's normal is its z axis; the camera sits on the side it faces,
    // whichever sign libapriltag's frame gives that side.
    view.tilt_deg = std::acos(std::min(1.0, std::abs(view.camera_direction_in_tag.z()))) * kRadToDeg;
    views.push_back(view);
  }
  return views;
}

void CoverageTracker::Add(FrameId frame, const std::vector<TagSighting>& views) {
  for (const TagSighting& view : views) {
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
