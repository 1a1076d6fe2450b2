// libapriltag 3.3's worker pool crashed when a detector was created, used
// once with 2 threads and destroyed, over and over (StartAprilTagWorkerPool
// explains the race). Without the safe start this loop crashed within
// 100-500 cycles on every run; a crash fails the test binary.
#include <gtest/gtest.h>

#include "tagsfm/detect/synthetic_tags.h"
#include "tagsfm/detect/tag_detector.h"

namespace tagsfm {
namespace {

TEST(AprilTagWorkerPool, CreateDetectDestroyCyclesWithTwoThreads) {
  PlacedTag tag;
  tag.id = 3;
  tag.corners = {Eigen::Vector2d(20, 60), Eigen::Vector2d(60, 60), Eigen::Vector2d(60, 20), Eigen::Vector2d(20, 20)};
  TagRenderOptions render;
  render.noise_sigma = 2.0;
  const Result<cv::Mat> image = RenderTags("tag16h5", 80, 80, {tag}, render);
  ASSERT_TRUE(image) << image.error().message;
  TagDetectorOptions options;
  options.family = "tag16h5";
  options.threads = 2;
  int found = 0;
  const int cycles = 600;
  for (int i = 0; i < cycles; ++i) {
    auto detector = TagDetector::Create(options);
    ASSERT_TRUE(detector) << detector.error().message;
    const Result<DetectionSet> detections = (*detector)->Detect(*image, i);
    ASSERT_TRUE(detections) << detections.error().message;
    found += static_cast<int>(detections->tags.size());
  }
  EXPECT_EQ(found, cycles);  // and every run found the tag
}

}  // namespace
}  // namespace tagsfm
