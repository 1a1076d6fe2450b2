// The acceptance test for the renderer: at zero noise and blur, the
// true target corners projected with the true poses land on the rendered
// corners within 0.1 px, measured from the rendered edges (no tag detector).
#include <gtest/gtest.h>

#include <cstdio>

#include "edge_corner_measure.h"
#include "tagsfm/capture/recording.h"
#include "tagsfm/core/csv_formats.h"
#include "tagsfm/synth/camera_path.h"
#include "tagsfm/synth/renderer.h"
#include "tagsfm/synth/scene_builder.h"
#include "tagsfm/synth/synthetic_recording.h"
#include "test_paths.h"

namespace tagsfm::synth {
namespace {

using testing::MeasureTagCorners;
using testing::TagFullyVisible;

// Box filtering with 4x4 jittered samples leaves each edge pixel's coverage
// with ~0.06 px of sampling noise; a line through 24 crossings averages it to
// ~0.015 px, a corner from two lines to ~0.03 px. 0.1 px is the bar.
constexpr double kMaxCornerErrorPx = 0.1;

// One face with one large tag, seen obliquely from close up.
Scene OneTagScene(double angle_rad) {
  Scene scene;
  scene.name = "test";
  scene.family = "tag36h11";
  SceneFace face;
  face.name = "panel";
  face.rect = Rectangle3d{{-0.15, 0, -0.15}, {0.3, 0, 0}, {0, 0, 0.3}};
  face.texture = MakeTexture(150, 150, 0.002, 5);
  scene.faces.push_back(face);
  PlacedTag tag;
  tag.id = 7;
  tag.face = 0;
  tag.centre_in_face = {0.15, 0.15};
  tag.angle_rad = angle_rad;
  tag.size_m = 0.1;
  tag.pattern = *LoadTagPattern("tag36h11", 7);
  scene.tags.push_back(tag);
  return scene;
}

void ExpectCloseUpCornersExact(const std::vector<double>& distortion) {
  const Scene scene = OneTagScene(0.35);
  CameraModel camera;
  camera.width = 320;
  camera.height = 240;
  camera.fx = camera.fy = 300;
  camera.cx = 159.5;
  camera.cy = 119.5;
  camera.distortion = distortion;
  Result<SceneRenderer> renderer = SceneRenderer::Create(camera, &scene, 4, 2);
  ASSERT_TRUE(renderer) << renderer.error().message;
  // Views from the front, from the side and from above; the panel faces -y.
  const Eigen::Vector3d eyes[] = {{0.02, -0.38, 0.01}, {0.25, -0.3, 0.05}, {-0.1, -0.3, 0.22}};
  for (const Eigen::Vector3d& eye : eyes) {
    const Rigid3d cam_from_world = LookAt(eye, Eigen::Vector3d(0.01, 0, -0.01), 0.2);
    const cv::Mat gray = ApplySensorModel(renderer->Render(cam_from_world), {1.0, 0.0}, 1);
    const auto measured =
        MeasureTagCorners(gray, camera, cam_from_world, TagCornersInWorld(scene, scene.tags[0]), scene.tags[0].pattern);
    ASSERT_TRUE(measured) << "tag not measurable from eye " << eye.transpose();
    EXPECT_LT(measured->max_error_px, kMaxCornerErrorPx) << "eye " << eye.transpose();
  }
}

TEST(CornerAccuracy, CloseUpTagWithoutDistortion) { ExpectCloseUpCornersExact({}); }

TEST(CornerAccuracy, CloseUpTagWithDistortion) { ExpectCloseUpCornersExact({-0.25, 0.08, 0.001, -0.0007, -0.01}); }

// The whole path: WriteSyntheticRecording, PNG, RecordingReader, ground_truth/.
void ExpectRecordingCornersExact(const std::vector<double>& distortion) {
  SynthOptions options;
  options.scene = "box";
  options.frames = 4;
  options.tag_size = 0.09;  // large tags: clean edge profiles on more of them
  options.width = 640;
  options.height = 480;
  options.fx = 900;  // narrow lens: tags large enough for clean edge profiles
  options.distortion = distortion;
  options.min_distance = 1.3;
  options.max_distance = 1.6;
  options.max_azimuth_deg = 40;
  options.noise = 0;
  options.blur = 0;
  tagsfm::testing::TempDir dir;
  Result<SynthSummary> summary = WriteSyntheticRecording(options, dir.path() / "rec");
  ASSERT_TRUE(summary) << summary.error().message;
  Result<RecordingReader> reader = RecordingReader::Open(dir.path() / "rec");
  ASSERT_TRUE(reader) << reader.error().message;
  Result<PoseMap> poses = ReadPosesCsv(dir.path() / "rec/ground_truth/poses.csv");
  Result<TargetCornerMap> targets = ReadTargetsCsv(dir.path() / "rec/ground_truth/targets.csv");
  ASSERT_TRUE(poses && targets);
  const Scene scene = *BuildScene(options);  // for the tag patterns and occlusion
  int measured_tags = 0;
  double worst = 0;
  for (size_t i = 0; i < reader->entries().size(); ++i) {
    Result<Frame> frame = reader->LoadFrame(i);
    ASSERT_TRUE(frame) << frame.error().message;
    const Rigid3d& cam_from_world = poses->at(frame->index);
    for (const PlacedTag& tag : scene.tags) {
      if (!TagFullyVisible(scene, tag, cam_from_world)) continue;
      const auto measured = MeasureTagCorners(frame->gray, *reader->info().camera, cam_from_world,
                                              targets->at(tag.id), tag.pattern);
      if (!measured) continue;
      ++measured_tags;
      worst = std::max(worst, measured->max_error_px);
      EXPECT_LT(measured->max_error_px, kMaxCornerErrorPx) << "frame " << frame->index << " tag " << tag.id;
    }
  }
  EXPECT_GE(measured_tags, 10) << "too few tags large and visible enough to measure";
  ::testing::Test::RecordProperty("worst_corner_error_px", std::to_string(worst));
  std::printf("worst corner error %.4f px over %d tags\n", worst, measured_tags);
}

// Whole recordings take ~10 s each under the sanitizers: Slow suite.
TEST(CornerAccuracySlow, RecordingWithoutDistortion) { ExpectRecordingCornersExact({}); }

TEST(CornerAccuracySlow, RecordingWithDistortion) { ExpectRecordingCornersExact({-0.2, 0.05, 0.0008, -0.0005}); }

}  // namespace
}  // namespace tagsfm::synth
