// SfM alone on rendered recordings with truth: the box and the wall, a
// video-like orbit and scattered photos, blur and lens distortion varied.
// Poses are compared after a similarity fit of the camera centres (SfM alone
// has no scale or world frame of its own); points against the true surfaces.
#include <algorithm>
#include <cmath>
#include <iostream>

#include <gtest/gtest.h>

#include "tagsfm/capture/recording.h"
#include "tagsfm/eval/scene_geometry.h"
#include "tagsfm/eval/similarity.h"
#include "tagsfm/sfm/incremental_mapper.h"
#include "tagsfm/synth/synthetic_recording.h"
#include "test_paths.h"

namespace tagsfm::sfm {
namespace {

namespace fs = std::filesystem;

struct SceneScore {
  int frames = 0, registered = 0, points = 0;
  double max_centre_error_m = 0, max_rotation_deg = 0;
  double within_2mm = 0, within_5mm = 0;
};

SceneScore RunScene(const synth::SynthOptions& options) {
  testing::TempDir dir;
  const fs::path rec = dir.path() / "rec";
  auto written = synth::WriteSyntheticRecording(options, rec);
  EXPECT_TRUE(written.has_value());
  auto reader = RecordingReader::Open(rec);
  EXPECT_TRUE(reader.has_value());
  const CameraModel camera = *reader->info().camera;
  std::vector<KeyframeFeatures> views;
  FeatureExtractorOptions extractor;
  extractor.max_features = 8192;
  for (size_t i = 0; i < reader->entries().size(); ++i) {
    auto frame = reader->LoadFrame(i);
    EXPECT_TRUE(frame.has_value());
    auto features = ExtractFeatures(frame->gray, cv::Mat(), DetectionSet{frame->index, {}}, extractor);
    EXPECT_TRUE(features.has_value());
    views.push_back(std::move(*features));
  }
  SceneScore score;
  score.frames = static_cast<int>(views.size());
  auto result = ReconstructIncremental(views, camera, {});
  EXPECT_TRUE(result.has_value()) << result.error().message;
  if (!result) return score;
  const PoseMap truth = *ReadPosesCsv(rec / "ground_truth/poses.csv");
  const auto surfaces = eval::ReadSceneYaml(rec / "ground_truth/scene.yaml");
  EXPECT_TRUE(surfaces.has_value());
  std::vector<Eigen::Vector3d> est, true_centres;
  std::vector<std::pair<Rigid3d, Rigid3d>> poses;
  for (const SfmImage& image : result->model.images) {
    if (!image.registered) continue;
    ++score.registered;
    est.push_back(image.cam_from_world.Center());
    true_centres.push_back(truth.at(image.frame).Center());
    poses.push_back({image.cam_from_world, truth.at(image.frame)});
  }
  auto sim = eval::EstimateSim3d(est, true_centres, true);
  EXPECT_TRUE(sim.has_value());
  if (!sim) return score;
  for (size_t i = 0; i < est.size(); ++i) {
    score.max_centre_error_m = std::max(score.max_centre_error_m, (*sim * est[i] - true_centres[i]).norm());
    score.max_rotation_deg = std::max(score.max_rotation_deg,
                                      RotationAngleDeg(sim->TransformPose(poses[i].first).rotation, poses[i].second.rotation));
  }
  for (const SfmPoint& p : result->model.points) {
    if (p.deleted) continue;
    ++score.points;
    const double d = eval::DistanceToSurfaces(*surfaces, *sim * p.xyz);
    score.within_2mm += d <= 2e-3;
    score.within_5mm += d <= 5e-3;
  }
  if (score.points > 0) {
    score.within_2mm /= score.points;
    score.within_5mm /= score.points;
  }
  std::cout << options.scene << "/" << options.path << " blur " << options.blur << (options.distortion.empty() ? "" : " distorted")
            << ": " << score.registered << "/" << score.frames << " registered, centres within " << score.max_centre_error_m * 1e3
            << " mm, rotations within " << score.max_rotation_deg << " deg, " << score.points << " points, "
            << score.within_2mm * 100 << " % within 2 mm, " << score.within_5mm * 100 << " % within 5 mm\n";
  return score;
}

synth::SynthOptions Small(const std::string& scene, const std::string& path, unsigned seed) {
  synth::SynthOptions options;
  options.scene = scene;
  options.path = path;
  options.frames = 10;
  options.width = 640;
  options.height = 360;
  options.seed = seed;
  return options;
}

// 640x360 (f = 500), 10 frames at 1.5-3 m: a pixel is 3-6 mm there.
// Measured 2026-12-02 (docs/features.md, SfM alone; deterministic, 2-3 min
// for the four): all 10/10 registered; centres within 0.21 / 0.61 / 0.25 /
// 0.59 mm and rotations within 0.009 / 0.032 / 0.032 / 0.028 deg after the
// similarity fit; 11,924 / 7,665 / 9,328 / 10,489 points, 43.7 / 39.8 /
// 62.4 / 45.7 % within 2 mm and 69.6 / 66.4 / 88.1 / 71.8 % within 5 mm
// (box orbit, box blurred and distorted, wall, box photos).
// Bounds: centres within 3 mm (a pixel at the near end; 5x the worst),
// rotations within 0.1 deg (0.9 px at f = 500; 3x the worst). The points
// are SIFT's pixels triangulated with COLMAP's limits (1.5 deg, 4 px), not
// the hybrid's refined ones, so the hybrid's > 85 % within 5 mm first
// guessed here does not apply: on the box orbit the points seen from >= 12
// deg apart are 86 % within 5 mm, those under 3 deg 26 %, and tracks of 6+
// views 98 %, those of 2 views 58 %: SIFT's localisation noise (a fraction
// of a pixel, itself 3-6 mm) along short baselines, not a bias. COLMAP's
// own model of recordings/box_small (640x480) is 74 % within 5 mm, SfM
// alone's 69 % (docs/features.md). So: > 55 % within
// 5 mm and > 30 % within 2 mm (about 10 points under the worst measured),
// more than 5,000 points (two thirds of the fewest).
TEST(SfmRenderedSlow, PosesAndPointsMatchTheTruthAcrossScenes) {
  std::vector<synth::SynthOptions> cases = {Small("box", "orbit", 3), Small("box", "orbit", 7), Small("wall", "orbit", 5),
                                            Small("box", "photos", 9)};
  cases[0].max_azimuth_deg = 35;
  cases[1].blur = 1.2;
  cases[1].max_azimuth_deg = 35;
  cases[1].distortion = {-0.12, 0.03, 0, 0};
  for (const synth::SynthOptions& options : cases) {
    const SceneScore s = RunScene(options);
    const std::string name = options.scene + "/" + options.path + " seed " + std::to_string(options.seed);
    EXPECT_EQ(s.registered, s.frames) << name;
    EXPECT_LT(s.max_centre_error_m, 0.003) << name;
    EXPECT_LT(s.max_rotation_deg, 0.1) << name;
    EXPECT_GT(s.points, 5000) << name;
    EXPECT_GT(s.within_2mm, 0.30) << name;
    EXPECT_GT(s.within_5mm, 0.55) << name;
  }
}

}  // namespace
}  // namespace tagsfm::sfm
