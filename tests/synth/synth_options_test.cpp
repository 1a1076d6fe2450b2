#include <gtest/gtest.h>

#include "tagsfm/synth/synth_options.h"

namespace tagsfm::synth {
namespace {

// The error names the flag at fault.
void ExpectRejected(const SynthOptions& options, const std::string& flag) {
  const Status status = options.Check();
  ASSERT_FALSE(status.ok()) << "accepted, expected an error about " << flag;
  EXPECT_NE(status.error().message.find(flag), std::string::npos) << status.error().message;
}

TEST(SynthOptions, DefaultsAreValid) {
  const SynthOptions options;
  EXPECT_TRUE(options.Check().ok());
  const CameraModel camera = options.Camera();
  EXPECT_EQ(camera.width, 1280);
  EXPECT_DOUBLE_EQ(camera.fx, 1000.0);
  // Pixel centres at integers: the image centre is at (W - 1) / 2.
  EXPECT_DOUBLE_EQ(camera.cx, 639.5);
  EXPECT_DOUBLE_EQ(camera.cy, 359.5);
}

TEST(SynthOptions, EachWrongFieldIsNamed) {
  SynthOptions o;
  o.scene = "castle";
  ExpectRejected(o, "--scene");
  o = SynthOptions();
  o.path = "spiral";
  ExpectRejected(o, "--path");
  o = SynthOptions();
  o.frames = 0;
  ExpectRejected(o, "--frames");
  o = SynthOptions();
  o.width = 3;
  ExpectRejected(o, "--width");
  o = SynthOptions();
  o.distortion = {0.1, 0.2, 0.3};
  ExpectRejected(o, "--distortion");
  o = SynthOptions();
  o.noise = -1;
  ExpectRejected(o, "--noise");
  o = SynthOptions();
  o.blur = -0.5;
  ExpectRejected(o, "--blur");
  o = SynthOptions();
  o.brightness = 0;
  ExpectRejected(o, "--brightness");
  o = SynthOptions();
  o.family = "tag99h1";
  ExpectRejected(o, "--family");
  o = SynthOptions();
  o.tag_size = 0;
  ExpectRejected(o, "--tag-size");
  o = SynthOptions();
  o.tag_margin = 0.5;  // less than the tag image's own white ring
  ExpectRejected(o, "--tag-margin");
  o = SynthOptions();
  o.min_distance = 3;
  o.max_distance = 2;
  ExpectRejected(o, "--distance");
  o = SynthOptions();
  o.samples = 0;
  ExpectRejected(o, "--samples");
  o = SynthOptions();
  o.max_azimuth_deg = 90;
  ExpectRejected(o, "--azimuth");
}

}  // namespace
}  // namespace tagsfm::synth
