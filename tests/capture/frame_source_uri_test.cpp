#include <gtest/gtest.h>

#include "tagsfm/capture/frame_source.h"

namespace tagsfm {
namespace {

TEST(FrameSourceUri, LibcameraNamesTheCameraNumberAndHowManyThereAre) {
  auto bad = OpenFrameSource("libcamera:front");
  ASSERT_FALSE(bad);
  EXPECT_EQ(bad.error().message, "camera source 'libcamera:front': expected libcamera:N, N the camera's number (0 for the first)");
  auto absent = OpenFrameSource("libcamera:99");
  ASSERT_FALSE(absent);
  // "no such camera (libcamera sees K)" with libcamera, else "no libcamera support".
  EXPECT_EQ(absent.error().message.rfind("libcamera:99: ", 0), 0u) << absent.error().message;
  EXPECT_TRUE(absent.error().message.find("no such camera (libcamera sees") != std::string::npos ||
              absent.error().message.find("no libcamera support") != std::string::npos)
      << absent.error().message;
}

TEST(FrameSourceUri, AV4l2NodeThatIsNotThereIsAOneLineError) {
  auto absent = OpenFrameSource("v4l2:/dev/video-tagsfm-absent");
  ASSERT_FALSE(absent);
  EXPECT_EQ(absent.error().message, "v4l2:/dev/video-tagsfm-absent: cannot open (No such file or directory)");
}

}  // namespace
}  // namespace tagsfm
