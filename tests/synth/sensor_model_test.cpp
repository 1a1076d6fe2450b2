#include <gtest/gtest.h>

#include <opencv2/core.hpp>

#include "tagsfm/capture/recording.h"
#include "tagsfm/core/file_util.h"
#include "tagsfm/synth/renderer.h"
#include "tagsfm/synth/synthetic_recording.h"
#include "test_paths.h"

namespace tagsfm::synth {
namespace {

TEST(SensorModel, NoiseStdMatchesSigmaOnAFlatRegion) {
  const cv::Mat1f flat(300, 300, 0.5f);
  for (double sigma : {1.0, 2.0, 5.0}) {
    const cv::Mat gray = ApplySensorModel(flat, {0.0, 1.0, sigma}, 42);
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
  EXPECT_NEAR(cv::mean(ApplySensorModel(flat, {0.0, 0.5, 0.0}, 1))[0], 0.6 * 0.5 * 255, 0.51);
  EXPECT_EQ(cv::mean(ApplySensorModel(flat, {0.0, 3.0, 0.0}, 1))[0], 255.0);
}

TEST(SensorModel, BlurKeepsTheMeanAndSoftensAnEdge) {
  cv::Mat1f step(40, 40, 0.2f);
  step.colRange(20, 40).setTo(0.8f);
  const cv::Mat sharp = ApplySensorModel(step, {0.0, 1.0, 0.0}, 1);
  const cv::Mat soft = ApplySensorModel(step, {1.5, 1.0, 0.0}, 1);
  EXPECT_NEAR(cv::mean(soft)[0], cv::mean(sharp)[0], 0.5);
  EXPECT_EQ(sharp.at<std::uint8_t>(20, 19), 51);
  EXPECT_GT(soft.at<std::uint8_t>(20, 19), 60);
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
