#pragma once
// Putting a new tag into the map from the registered frames that saw it, and
// starting a map without one. A single view of a square has two poses that
// fit it almost equally (IPPE's planar ambiguity); more views decide.
#include <optional>
#include <vector>

#include "tagsfm/recon/reconstruction.h"

namespace tagsfm {

struct TagView {
  const FrameState* frame = nullptr;  // registered
  const TagObservation* observation = nullptr;
};

struct TagInitialization {
  Rigid3d world_from_tag;
  double rms_px = 0;
};

// Reprojection RMS (px) of a tag pose over the views; infinity when a corner
// falls behind a camera or the tag faces away from one.
double TagPoseRmsPx(const Rigid3d& world_from_tag, double size_m, const std::vector<TagView>& views, double fx,
                    double fy);

// The best of every view's IPPE candidates, refined over all views with the
// cameras held fixed. nullopt when nothing fits.
std::optional<TagInitialization> InitializeTag(const std::vector<TagView>& views, double size_m, double fx, double fy);

// The widest angle (degrees) between two views' rays to `point_in_world`.
double MaxViewAngleDeg(const std::vector<TagView>& views, const Eigen::Vector3d& point_in_world);

// Two frames sharing tags: the world is the anchor tag's frame; both cameras'
// poses and the other shared tags' poses are chosen among the IPPE
// candidates to fit both views best.
struct TwoViewBootstrap {
  TagId anchor = -1;
  Rigid3d first_cam_from_world, second_cam_from_world;
  std::map<TagId, Rigid3d> world_from_tag;  // the shared tags, anchor included (identity)
  double rms_px = 0;
  double view_angle_deg = 0;
};
std::optional<TwoViewBootstrap> BootstrapFromTwoViews(const FrameState& first, const FrameState& second,
                                                      const std::map<TagId, double>& size_by_tag, double fx,
                                                      double fy);

}  // namespace tagsfm
