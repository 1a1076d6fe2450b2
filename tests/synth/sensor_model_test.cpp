#include <cmath>
#include <iostream>

#include <gtest/gtest.h>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "tagsfm/capture/recording.h"
#include "tagsfm/core/file_util.h"
#include "tagsfm/synth/camera_path.h"
#include "tagsfm/synth/renderer.h"
#include "tagsfm/synth/scene_builder.h"
#include "tagsfm/synth/synthetic_recording.h"
#include "test_paths.h"

namespace tagsfm::synth {
namespace {

TEST(SensorModel, NoiseStdMatchesSigmaOnAFlatRegion) {
  const cv::Mat1f flat(300, 300, 0.5f);
  for (double sigma : {1.0, 2.0, 5.0}) {
    const cv::Mat gray = ApplySensorModel(flat, {1.0, sigma}, 42);
    cv::Scalar mean, stddev;
    cv::meanStdDev(gray, mean, stddev);
    // 90000 samples: the std estimate itself is within ~0.5%; quantisation
    // adds 1/12 grey level^2 of variance, 2% at sigma = 1.
    EXPECT_NEAR(stddev[0], sigma, 0.1 * sigma) << "sigma " << sigma;
    EXPECT_NEAR(mean[0], 127.5, 0.2);
  }
}

TEST(SensorModel, BrightnessScalesAndSaturates) {
  const cv::Mat1f flat(50, 50, 0.6f);
  EXPECT_NEAR(cv::mean(ApplySensorModel(flat, {0.5, 0.0}, 1))[0], 0.6 * 0.5 * 255, 0.51);
  EXPECT_EQ(cv::mean(ApplySensorModel(flat, {3.0, 0.0}, 1))[0], 255.0);
}

// A pixel that a straight edge at x0 crosses collects, through a Gaussian
// lens blur of std s and then its square footprint [i - 1/2, i + 1/2], the
// fraction s (G((i + 1/2 - x0) / s) - G((i - 1/2 - x0) / s)) of the far side's
// light, with G(z) = z Phi(z) + phi(z) (the antiderivative of Phi).
double IntegratedEdgeFraction(int i, double x0, double s) {
  const auto g = [](double z) {
    return z * 0.5 * std::erfc(-z / std::sqrt(2.0)) + std::exp(-0.5 * z * z) / std::sqrt(2.0 * M_PI);
  };
  return s * (g((i + 0.5 - x0) / s) - g((i - 0.5 - x0) / s));
}

// The renderer blurs before the pixels integrate: across a tag's left edge,
// seen head-on, the mean profile over 60 rows matches the exact integrated
// profile. Blurring the integrated pixels instead (what the renderer did
// before) is measurably off at the blurs the recordings use.
TEST(SceneRenderer, LensBlurActsBeforeThePixelsIntegrate) {
  Scene scene;
  scene.name = "edge";
  SceneFace face;
  face.rect = Rectangle3d{{-0.15, 0, -0.15}, {0.3, 0, 0}, {0, 0, 0.3}};
  face.texture = cv::Mat1f(4, 4, 0.5f);
  scene.faces.push_back(face);
  PlacedTag tag;
  tag.id = 0;
  tag.face = 0;
  tag.centre_in_face = {0.15, 0.15};
  tag.size_m = 0.1;
  tag.margin_modules = 2.0;  // the profile's white reference lies 6-10 px (0.7-1.1 modules) outside
  tag.pattern = *LoadTagPattern("tag36h11", 0);
  scene.tags.push_back(tag);
  CameraModel camera;
  camera.width = 160;
  camera.height = 120;
  camera.fx = camera.fy = 300;
  camera.cx = 79.5 + 0.3;  // the edge off the pixel grid
  camera.cy = 59.5;
  const Rigid3d cam_from_world = LookAt({0, -0.4, 0}, {0, 0, 0}, 0.0);
  const Eigen::Vector3d corner_in_world = TagCornersInWorld(scene, scene.tags[0])[0];  // bottom-left
  const double x0 = camera.Project(cam_from_world * corner_in_world).x();
  Result<SceneRenderer> renderer = SceneRenderer::Create(camera, &scene, 8, 2);
  ASSERT_TRUE(renderer) << renderer.error().message;
  const int edge = static_cast<int>(std::lround(x0));
  // Mean fraction of black across the edge, over rows well inside the tag.
  const auto profile_error = [&](const cv::Mat1f& light, double blur) {
    double worst = 0.0;
    const int rows = 60;
    const double white = cv::mean(light(cv::Rect(edge - 10, 30, 4, rows)))[0];
    const double black = cv::mean(light(cv::Rect(edge + 4, 30, 2, rows)))[0];
    for (int i = edge - 2; i <= edge + 2; ++i) {
      const double measured = (cv::mean(light(cv::Rect(i, 30, 1, rows)))[0] - white) / (black - white);
      worst = std::max(worst, std::abs(measured - IntegratedEdgeFraction(i, x0, blur)));
    }
    return worst;
  };
  for (double blur : {0.5, 0.7}) {
    const cv::Mat1f lens_first = renderer->Render(cam_from_world, blur);
    cv::Mat1f pixels_first;
    cv::GaussianBlur(renderer->Render(cam_from_world), pixels_first, cv::Size(), blur, blur, cv::BORDER_REFLECT);
    const double error = profile_error(lens_first, blur), old_error = profile_error(pixels_first, blur);
    std::cout << "blur " << blur << ": profile error " << error << " (blurring the pixels: " << old_error << ")\n";
    EXPECT_LT(error, 0.002) << "blur " << blur;  // measured 0.0008, 0.0006
    EXPECT_GT(old_error, 0.01) << "blur " << blur;  // measured 0.041, 0.018
  }
}

TEST(SyntheticRecording, SameSeedSameImagesOtherSeedOtherImages) {
  SynthOptions options;
  options.width = 160;
  options.height = 120;
  options.frames = 2;
  tagsfm::testing::TempDir dir;
  ASSERT_TRUE(WriteSyntheticRecording(options, dir.path() / "a"));
  ASSERT_TRUE(WriteSyntheticRecording(options, dir.path() / "b"));
  options.seed = 2;
  ASSERT_TRUE(WriteSyntheticRecording(options, dir.path() / "c"));
  for (const char* frame : {"frames/000000.png", "frames/000001.png"}) {
    const std::string a = *ReadFileToString(dir.path() / "a" / frame);
    EXPECT_EQ(a, *ReadFileToString(dir.path() / "b" / frame)) << frame;
    EXPECT_NE(a, *ReadFileToString(dir.path() / "c" / frame)) << frame;
  }
  EXPECT_EQ(*ReadFileToString(dir.path() / "a/ground_truth/poses.csv"),
            *ReadFileToString(dir.path() / "b/ground_truth/poses.csv"));
}

TEST(SyntheticRecording, WithMapWritesTheTrueMapAndNamesIt) {
  SynthOptions options;
  options.scene = "wall";
  options.width = 160;
  options.height = 120;
  options.frames = 1;
  options.with_map = true;
  tagsfm::testing::TempDir dir;
  ASSERT_TRUE(WriteSyntheticRecording(options, dir.path() / "rec"));
  Result<RecordingReader> reader = RecordingReader::Open(dir.path() / "rec");
  ASSERT_TRUE(reader) << reader.error().message;
  Result<std::optional<TargetCornerMap>> map = reader->LoadTargetMap();
  ASSERT_TRUE(map && map->has_value());
  EXPECT_EQ((*map)->size(), 24u);
  EXPECT_EQ(*ReadFileToString(dir.path() / "rec/targets.csv"),
            *ReadFileToString(dir.path() / "rec/ground_truth/targets.csv"));
}

TEST(SyntheticRecording, RefusesToOverwriteARecording) {
  SynthOptions options;
  options.width = 64;
  options.height = 48;
  options.frames = 1;
  tagsfm::testing::TempDir dir;
  ASSERT_TRUE(WriteSyntheticRecording(options, dir.path() / "rec"));
  Result<SynthSummary> again = WriteSyntheticRecording(options, dir.path() / "rec");
  ASSERT_FALSE(again);
  EXPECT_NE(again.error().message.find("rec"), std::string::npos);
}

}  // namespace
}  // namespace tagsfm::synth
