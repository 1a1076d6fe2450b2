// A recording without a camera block: `tagsfm calibrate` estimates the
// intrinsics from the targets, adjusts them as replay does, and writes them; `replay` calibrates by itself
// and refines the intrinsics in the final adjustment.
#include <sys/wait.h>

#include <cstdlib>
#include <fstream>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "tagsfm/capture/recording.h"
#include "tagsfm/core/file_util.h"
#include "test_paths.h"

namespace tagsfm {
namespace {

namespace fs = std::filesystem;

// box_small without its camera block (truth: fx = fy = 500, cx 319.5, cy 239.5).
fs::path CopyWithoutCamera(const fs::path& scratch) {
  const fs::path rec = scratch / "rec";
  fs::copy(testing::RecordingsDir() / "box_small", rec, fs::copy_options::recursive);
  auto info = ReadRecordingYaml(rec / "recording.yaml");
  EXPECT_TRUE(info.has_value());
  info->camera.reset();
  EXPECT_TRUE(WriteFileAtomically(rec / "recording.yaml", RecordingYamlText(*info)).ok());
  return rec;
}

int Tagsfm(const std::string& args) {
  const int status = std::system((testing::TagsfmExe().string() + " " + args + " > /dev/null 2>&1").c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

TEST(ReplayCalibrateSlow, CalibrateWritesTheCameraBlock) {
  testing::TempDir scratch;
  const fs::path rec = CopyWithoutCamera(scratch.path());
  ASSERT_EQ(Tagsfm("calibrate " + rec.string()), 0);
  auto info = ReadRecordingYaml(rec / "recording.yaml");
  ASSERT_TRUE(info.has_value());
  ASSERT_TRUE(info->camera.has_value());
  // Calibrated from the tag views, then adjusted with every frame's pose
  // and the map, as replay does: measured fx 500.4, fy 500.1, cx 319.2,
  // cy 240.1 (the first estimate alone was 504.5 / 502.7 / 317.5 / 243.1).
  // Bounds: 0.5 % and 3 px.
  EXPECT_NEAR(info->camera->fx, 500, 2.5);
  EXPECT_NEAR(info->camera->fy, 500, 2.5);
  EXPECT_NEAR(info->camera->cx, 319.5, 3);
  EXPECT_NEAR(info->camera->cy, 239.5, 3);
  // A second run without --force refuses to overwrite.
  EXPECT_NE(Tagsfm("calibrate " + rec.string()), 0);
}

TEST(ReplayCalibrateSlow, ReplayRefinesTheIntrinsicsInTheFinalAdjustment) {
  testing::TempDir scratch;
  const fs::path rec = CopyWithoutCamera(scratch.path());
  const fs::path out = scratch.path() / "out";
  ASSERT_EQ(Tagsfm("replay " + rec.string() + " --out " + out.string()), 0);
  auto text = ReadFileToString(out / "report.json");
  ASSERT_TRUE(text.has_value());
  const nlohmann::json report = nlohmann::json::parse(*text);
  EXPECT_TRUE(report["intrinsics_refined"].get<bool>());
  // Measured after refinement: fx 500.3, fy 501.0, cx 319.3, cy 237.0.
  EXPECT_NEAR(report["camera"]["fx"].get<double>(), 500, 5);
  EXPECT_NEAR(report["camera"]["fy"].get<double>(), 500, 5);
  EXPECT_NEAR(report["camera"]["cx"].get<double>(), 319.5, 6);
  EXPECT_NEAR(report["camera"]["cy"].get<double>(), 239.5, 6);
  EXPECT_EQ(report["registered_frames"].get<int>(), 20);
}

}  // namespace
}  // namespace tagsfm
