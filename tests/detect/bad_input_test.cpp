// Bad input gets a clear result or a clear error, never a crash.
#include <fstream>

#include <gtest/gtest.h>

#include "tagsfm/capture/recording.h"
#include "tagsfm/detect/tag_detector.h"
#include "test_paths.h"

namespace tagsfm {
namespace {

std::unique_ptr<TagDetector> DefaultDetector() {
  auto detector = TagDetector::Create(TagDetectorOptions{});
  EXPECT_TRUE(detector.has_value());
  return std::move(*detector);
}

TEST(BadInput, EmptyAndTinyImagesGiveNoTags) {
  auto detector = DefaultDetector();
  for (const cv::Size size : {cv::Size(0, 0), cv::Size(1, 1), cv::Size(3, 2), cv::Size(9, 9), cv::Size(1, 500),
                              cv::Size(500, 1), cv::Size(17, 13)}) {
    const cv::Mat image(size, CV_8UC1, cv::Scalar(128));
    auto found = detector->Detect(image, 7);
    ASSERT_TRUE(found.has_value()) << size;
    EXPECT_TRUE(found->tags.empty()) << size;
    EXPECT_EQ(found->frame, 7);
  }
}

TEST(BadInput, WrongImageTypesAreClearErrors) {
  auto detector = DefaultDetector();
  for (const int type : {CV_16UC1, CV_8UC3, CV_8UC4, CV_32FC1}) {
    const cv::Mat image(64, 64, type, cv::Scalar::all(1));
    auto found = detector->Detect(image, 3);
    ASSERT_FALSE(found.has_value()) << type;
    EXPECT_NE(found.error().message.find("frame 3"), std::string::npos) << found.error().message;
    EXPECT_NE(found.error().message.find("8-bit single-channel"), std::string::npos) << found.error().message;
  }
}

TEST(BadInput, CorruptAndEmptyFilesAreClearErrors) {
  testing::TempDir dir;
  const auto empty = dir.path() / "empty.png";
  std::ofstream(empty).close();
  const auto corrupt = dir.path() / "corrupt.png";
  std::ofstream(corrupt) << "\x89PNG\r\n\x1a\n this is not a png";
  for (const auto& file : {empty, corrupt, dir.path() / "missing.png"}) {
    auto frame = LoadImageFrame(file, 0, 0);
    ASSERT_FALSE(frame.has_value()) << file;
    EXPECT_NE(frame.error().message.find(file.filename().string()), std::string::npos) << frame.error().message;
  }
}

TEST(BadInput, OptionsNameTheWrongField) {
  TagDetectorOptions options;
  options.family = "tag99h99";
  auto detector = TagDetector::Create(options);
  ASSERT_FALSE(detector.has_value());
  EXPECT_NE(detector.error().message.find("family"), std::string::npos);
  options = TagDetectorOptions{};
  options.quad_decimate = 0.0f;
  detector = TagDetector::Create(options);
  ASSERT_FALSE(detector.has_value());
  EXPECT_NE(detector.error().message.find("quad_decimate"), std::string::npos);
  options = TagDetectorOptions{};
  options.max_hamming = 3;
  EXPECT_FALSE(TagDetector::Create(options).has_value());
  EXPECT_FALSE(ParseCornerRefinement("subpixel").has_value());
  EXPECT_EQ(*ParseCornerRefinement("edgelinefit"), CornerRefinement::kEdgeLineFit);
}

// Every family libapriltag knows can be created (and freed: ASan checks).
TEST(BadInput, EveryKnownFamilyCreates) {
  for (const std::string& family : KnownTagFamilies()) {
    TagDetectorOptions options;
    options.family = family;
    auto detector = TagDetector::Create(options);
    ASSERT_TRUE(detector.has_value()) << family;
    const cv::Mat image(40, 40, CV_8UC1, cv::Scalar(200));
    EXPECT_TRUE((*detector)->Detect(image, 0).has_value()) << family;
  }
}

}  // namespace
}  // namespace tagsfm
