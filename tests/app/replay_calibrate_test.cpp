// A recording without a camera block: `tagsfm calibrate` estimates the
// intrinsics from the targets, adjusts them as replay does, and writes them; `replay` calibrates by itself
// and refines the intrinsics in the final adjustment.
#include <sys/wait.h>

#include <cmath>
#include <cstdlib>
#include <fstream>
#include <map>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "json_file.h"
#include "tagsfm/capture/recording.h"
#include "tagsfm/core/file_util.h"
#include "test_paths.h"

namespace tagsfm {
namespace {

namespace fs = std::filesystem;

// Takes the camera block out of `rec`'s recording.yaml: tagsfm must calibrate.
void DropCameraBlock(const fs::path& rec) {
  auto info = ReadRecordingYaml(rec / "recording.yaml");
  ASSERT_TRUE(info.has_value());
  info->camera.reset();
  ASSERT_TRUE(WriteFileAtomically(rec / "recording.yaml", RecordingYamlText(*info)).ok());
}

// box_small without its camera block (truth: fx = fy = 500, cx 319.5, cy 239.5).
fs::path CopyWithoutCamera(const fs::path& scratch) {
  const fs::path rec = scratch / "rec";
  fs::copy(testing::RecordingsDir() / "box_small", rec, fs::copy_options::recursive);
  DropCameraBlock(rec);
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
  const nlohmann::json report = testing::ReadJsonFile(out / "report.json");
  EXPECT_TRUE(report["intrinsics_refined"].get<bool>());
  // Measured after refinement: fx 500.3, fy 501.0, cx 319.3, cy 237.0.
  EXPECT_NEAR(report["camera"]["fx"].get<double>(), 500, 5);
  EXPECT_NEAR(report["camera"]["fy"].get<double>(), 500, 5);
  EXPECT_NEAR(report["camera"]["cx"].get<double>(), 319.5, 6);
  EXPECT_NEAR(report["camera"]["cy"].get<double>(), 239.5, 6);
  EXPECT_EQ(report["registered_frames"].get<int>(), 20);
  // Each parameter's sigma from the adjustment, and the truth within 3 of
  // them (measured: sigma 0.22-0.25 px, errors 0.004-0.1 sigma).
  const nlohmann::json& sigma = report["intrinsics_sigma"];
  ASSERT_TRUE(sigma.is_object());
  const std::map<std::string, double> truth = {{"fx", 500}, {"fy", 500}, {"cx", 319.5}, {"cy", 239.5}};
  for (const auto& [name, value] : truth) {
    const double s = sigma[name].get<double>();
    EXPECT_GT(s, 0.01) << name;
    EXPECT_LT(s, 1.0) << name;
    EXPECT_LT(std::abs(report["camera"][name].get<double>() - value), 3 * s) << name;
  }
  EXPECT_TRUE(report["intrinsics_unconstrained"].empty());
  // The pixels are square and the data do not say otherwise: one focal length.
  EXPECT_TRUE(report["square_pixels"].get<bool>());
  EXPECT_NEAR(report["camera"]["fx"].get<double>(), report["camera"]["fy"].get<double>(), 1e-3);
}

// A camera whose pixels are 2 % taller than wide: the free fit's fx - fy is
// far beyond its sigma, so both stay free (measured fx 500.40 +- 0.75, fy
// 510.13 +- 0.70).
TEST(ReplayCalibrateSlow, PixelsThatAreNotSquareStaySo) {
  testing::TempDir scratch;
  const fs::path rec = scratch.path() / "oblong";
  ASSERT_EQ(Tagsfm("synth box --out " + rec.string() + " --frames 20 --width 640 --height 480 --fx 500 --fy 510 --seed 4"), 0);
  DropCameraBlock(rec);
  if (::testing::Test::HasFatalFailure()) return;
  const fs::path out = scratch.path() / "out";
  ASSERT_EQ(Tagsfm("replay " + rec.string() + " --no-features --out " + out.string()), 0);
  const nlohmann::json report = testing::ReadJsonFile(out / "report.json");
  EXPECT_FALSE(report["square_pixels"].get<bool>());
  const std::map<std::string, double> truth = {{"fx", 500}, {"fy", 510}};
  for (const auto& [name, value] : truth) {
    const double s = report["intrinsics_sigma"][name].get<double>();
    EXPECT_LT(std::abs(report["camera"][name].get<double>() - value), 3 * s) << name;
  }
}

// Frontal views of a flat wall from one distance: the focal length trades
// against the distance, and calibrate says so instead of writing it.
TEST(ReplayCalibrateSlow, CalibrateRefusesViewsThatDoNotConstrainTheFocalLength) {
  testing::TempDir scratch;
  const fs::path rec = scratch.path() / "flat";
  ASSERT_EQ(Tagsfm("synth wall --out " + rec.string() + " --frames 8 --width 640 --height 480 --fx 500 "
                   "--distortion=-0.05,0,0,0 --azimuth 3 --distance 1.0,1.05 --seed 5"),
            0);
  DropCameraBlock(rec);
  if (::testing::Test::HasFatalFailure()) return;
  const fs::path log = scratch.path() / "calibrate.log";
  const int status = std::system((testing::TagsfmExe().string() + " calibrate " + rec.string() + " > " + log.string() + " 2>&1").c_str());
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_NE(WEXITSTATUS(status), 0);
  const auto text = ReadFileToString(log);
  ASSERT_TRUE(text.has_value());
  EXPECT_NE(text->find("do not constrain the intrinsics: fx: sigma"), std::string::npos) << *text;
  auto unchanged = ReadRecordingYaml(rec / "recording.yaml");
  ASSERT_TRUE(unchanged.has_value());
  EXPECT_FALSE(unchanged->camera.has_value());
  // Told to, it writes the estimate.
  ASSERT_EQ(Tagsfm("calibrate --accept-unconstrained " + rec.string()), 0);
  auto written = ReadRecordingYaml(rec / "recording.yaml");
  ASSERT_TRUE(written.has_value());
  ASSERT_TRUE(written->camera.has_value());
  EXPECT_NEAR(written->camera->fx, 500, 25);  // measured 501.5, sigma 1.4 px
}

}  // namespace
}  // namespace tagsfm
