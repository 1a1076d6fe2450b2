#include "tagsfm/recon/bundle_adjuster.h"

#include <deque>
#include <random>

#include <gtest/gtest.h>

#include "tagsfm/recon/tag_geometry.h"
#include "tagsfm/synth/box_scene.h"

namespace tagsfm {
namespace {

// Frames and tags of a synthetic scene, as the reconstructor would hold them.
struct Problem {
  synth::SyntheticScene scene;
  std::deque<FrameState> frames;
  std::map<TagId, MapTag> tags;
};

Problem MakeProblem(double noise_px, int frames) {
  Problem p;
  synth::SyntheticSceneOptions options;
  options.frames = frames;
  options.noise_px = noise_px;
  p.scene = synth::MakeSyntheticBoxScene(options);
  for (size_t i = 0; i < p.scene.detections.size(); ++i) {
    FrameState& f = p.frames.emplace_back();
    f.frame = static_cast<FrameId>(i);
    f.registered = true;
    f.cam_from_world.Set(p.scene.cam_from_world[i]);
    for (const auto& d : p.scene.detections[i].tags) {
      TagObservation obs;
      obs.id = d.id;
      obs.pixels = d.corners;
      for (int k = 0; k < 4; ++k) obs.normalized[k] = p.scene.camera.PixelToNormalized(d.corners[k]);
      f.tags.push_back(obs);
    }
  }
  for (const auto& [id, corners] : p.scene.targets) {
    MapTag tag;
    tag.id = id;
    tag.size_m = options.tag_size_m;
    tag.world_from_tag.Set(FitTagPose(corners, tag.size_m));
    p.tags[id] = tag;
  }
  return p;
}

Rigid3d Perturb(const Rigid3d& pose, double angle_rad, double shift_m, std::mt19937* rng) {
  std::normal_distribution<double> n(0, 1);
  const Eigen::Vector3d axis = Eigen::Vector3d(n(*rng), n(*rng), n(*rng)).normalized();
  return Rigid3d(Eigen::Quaterniond(Eigen::AngleAxisd(angle_rad, axis)) * pose.rotation,
                 pose.translation + shift_m * Eigen::Vector3d(n(*rng), n(*rng), n(*rng)).normalized());
}

TEST(BundleAdjuster, GlobalAdjustmentRecoversPerturbedPosesAndTargets) {
  // Noise-free observations, poses off by 1 deg / 2 cm, tags by 1 deg / 1 cm,
  // the anchor tag (id 0) held fixed: the adjustment must return to the
  // truth (errors ~0, limited by the solver's tolerances).
  Problem p = MakeProblem(0.0, 20);
  std::mt19937 rng(5);
  for (auto& f : p.frames) f.cam_from_world.Set(Perturb(f.cam_from_world.ToRigid(), 0.017, 0.02, &rng));
  for (auto& [id, tag] : p.tags) {
    tag.anchor = id == 0;
    if (!tag.anchor) tag.world_from_tag.Set(Perturb(tag.world_from_tag.ToRigid(), 0.017, 0.01, &rng));
  }
  std::vector<FrameState*> frames;
  for (auto& f : p.frames) frames.push_back(&f);
  const GlobalAdjustmentSummary summary =
      AdjustGlobally(frames, &p.tags, p.scene.camera.fx, p.scene.camera.fy, BundleAdjusterOptions{});
  EXPECT_GT(summary.initial_rms_px, 5.0);
  EXPECT_LT(summary.final_rms_px, 1e-4);
  for (size_t i = 0; i < p.frames.size(); ++i) {
    const Rigid3d pose = p.frames[i].cam_from_world.ToRigid();
    EXPECT_LT(RotationAngleDeg(pose.rotation, p.scene.cam_from_world[i].rotation), 1e-4) << "frame " << i;
    EXPECT_LT((pose.Center() - p.scene.cam_from_world[i].Center()).norm(), 1e-5) << "frame " << i;
  }
  for (const auto& [id, tag] : p.tags) {
    const TagCorners corners = tag.CornersInWorld();
    for (int k = 0; k < 4; ++k) EXPECT_LT((corners[k] - p.scene.targets.at(id)[k]).norm(), 1e-5) << "tag " << id;
    // The known size holds exactly: the tag is a square of that edge.
    for (double edge : TagEdgeLengths(corners)) EXPECT_NEAR(edge, 0.06, 1e-12);
  }
}

// What the reconstructor does with a window's solution.
void Apply(const WindowSolution& solution, Problem* p) {
  for (const auto& [frame, pose] : solution.cam_from_world) p->frames[static_cast<size_t>(frame)].cam_from_world = pose;
  for (const auto& [id, pose] : solution.world_from_tag) p->tags.at(id).world_from_tag = pose;
}

TEST(BundleAdjuster, SlidingWindowStaysBoundedAndImprovesPerturbedTags) {
  // 30 keyframes through a window of 6: the problem never holds more than
  // 6 frames' residuals, and perturbed tags return to the truth (noise-free
  // corners: with noise, a tag seen from one window frame only keeps a depth
  // error of ~Z^2 sigma / (f s) = 5 mm at 2.5 m, which the final global
  // adjustment removes, not the window).
  Problem p = MakeProblem(0.0, 30);
  std::mt19937 rng(9);
  for (auto& [id, tag] : p.tags) {
    tag.anchor = id == 0;
    if (!tag.anchor) tag.world_from_tag.Set(Perturb(tag.world_from_tag.ToRigid(), 0.005, 0.003, &rng));
  }
  auto tag_error = [&p] {
    double sum = 0;
    for (const auto& [id, tag] : p.tags) {
      const TagCorners c = tag.CornersInWorld();
      for (int k = 0; k < 4; ++k) sum += (c[k] - p.scene.targets.at(id)[k]).squaredNorm();
    }
    return std::sqrt(sum / (4.0 * p.tags.size()));
  };
  const double before = tag_error();
  BundleAdjusterOptions options;
  options.window_keyframes = 6;
  SlidingWindowBundleAdjuster window(options, p.scene.camera.fx, p.scene.camera.fy);
  size_t max_blocks = 0, max_observations = 0;
  for (size_t i = 0; i < p.frames.size(); ++i) {
    window.AddKeyframe(p.frames[i], p.tags);
    Apply(window.Solve(), &p);
    EXPECT_LE(window.keyframes(), 6u);
    max_blocks = std::max(max_blocks, window.residual_blocks());
    max_observations = std::max(max_observations, p.frames[i].tags.size());
  }
  EXPECT_LE(max_blocks, 6 * max_observations);  // one block per tag observation
  EXPECT_LT(tag_error(), 0.01 * before) << "before " << before;
}

}  // namespace
}  // namespace tagsfm

namespace tagsfm {
namespace {

TEST(BundleAdjuster, AWindowSolveThatFailsLeavesPosesAndTagsAsTheyWere) {
  Problem p = MakeProblem(0.1, 4);
  // A corner the detector should never hand on, but degenerate input must not
  // turn into a NaN pose: the solve cannot evaluate its first step.
  p.frames[1].tags[0].normalized[2] = Eigen::Vector2d(std::nan(""), 0.0);
  p.tags.begin()->second.anchor = true;
  BundleAdjusterOptions options;
  options.window_keyframes = 2;
  SlidingWindowBundleAdjuster window(options, p.scene.camera.fx, p.scene.camera.fy);
  window.AddKeyframe(p.frames[0], p.tags);
  window.AddKeyframe(p.frames[1], p.tags);
  const WindowSolution failed = window.Solve();
  EXPECT_FALSE(failed.solved);
  EXPECT_TRUE(failed.cam_from_world.empty());
  EXPECT_TRUE(failed.world_from_tag.empty());
  window.AddKeyframe(p.frames[2], p.tags);  // frame 1 with its NaN corner still in the window
  EXPECT_FALSE(window.Solve().solved);
  EXPECT_EQ(window.failed_solves(), 2);
  // Once the bad frame has left, the window solves from where the failed
  // solves found it: frame 2 (now the fixed oldest) and its tags as given.
  window.AddKeyframe(p.frames[3], p.tags);
  const WindowSolution solved = window.Solve();
  ASSERT_TRUE(solved.solved);
  ASSERT_EQ(solved.cam_from_world.size(), 2u);
  // Two views of free tags at 0.1 px noise: a camera's place is good to
  // ~Z^2 sigma / (f s) = 5 mm at 2.5 m (6 cm tags), 2 cm is 4 of those. A
  // NaN or a pose left where a failed solve gave up would be far outside.
  for (const auto& [frame, pose] : solved.cam_from_world) {
    const Rigid3d truth = p.scene.cam_from_world[static_cast<size_t>(frame)];
    EXPECT_LT((pose.ToRigid().Center() - truth.Center()).norm(), 0.02) << "frame " << frame;
  }
  EXPECT_EQ(solved.cam_from_world.front().second.ToRigid().translation, p.frames[2].cam_from_world.ToRigid().translation);
}

}  // namespace
}  // namespace tagsfm
