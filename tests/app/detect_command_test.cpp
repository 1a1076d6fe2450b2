// tagsfm detect IMAGE...: JSON per image, the small-tag pass on request, and
// an unreadable image named while the others are still reported.
#include <sys/wait.h>

#include <cstdlib>
#include <fstream>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <set>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "json_file.h"
#include "run_command.h"
#include "tagsfm/capture/recording.h"
#include "tagsfm/core/csv_formats.h"
#include "test_paths.h"

namespace tagsfm {
namespace {

using testing::ReadJsonFile;
using testing::ReadText;
using testing::RunCommand;
using testing::TempDir;

std::set<int> Ids(const nlohmann::json& image) {
  std::set<int> ids;
  for (const auto& tag : image["tags"]) ids.insert(tag["id"].get<int>());
  return ids;
}

// IMG_1451 lists tags 4-10, 12 and 14; at ~2 px modules libapriltag finds
// no quad for 7, 8 and 9 (docs/detection.md); the small-tag pass, on by
// default, reads all three (8 by one sample per module, 7 and 9 by the blur
// model); --no-small-tags leaves libapriltag's; --small-tags for a family the
// pass cannot read is an error naming it.
TEST(DetectCommand, SmallTagPassReadsTheSmallTagsOfARealPhotoByDefault) {
  TAGSFM_REQUIRE_SHARED_DATA("swatbotics-mapping/images/mapping_feb_2014");
  const auto image = testing::SharedDataDir() / "swatbotics-mapping/images/mapping_feb_2014/IMG_1451.JPG";
  TempDir tmp;
  const std::string base = testing::TagsfmExe().string() + " detect " + image.string() + " --decimate 1";
  ASSERT_EQ(RunCommand(base + " --no-small-tags", tmp.path() / "plain.json"), 0) << ReadText(tmp.path() / "plain.json");
  ASSERT_EQ(RunCommand(base, tmp.path() / "default.json"), 0);
  ASSERT_EQ(RunCommand(base + " --small-tags", tmp.path() / "small.json"), 0);
  const auto plain = ReadJsonFile(tmp.path() / "plain.json");
  const auto by_default = ReadJsonFile(tmp.path() / "default.json");
  const auto small = ReadJsonFile(tmp.path() / "small.json");
  ASSERT_EQ(plain.size(), 1u);
  ASSERT_EQ(by_default.size(), 1u);
  ASSERT_EQ(small.size(), 1u);
  EXPECT_EQ(Ids(plain[0]), (std::set<int>{4, 5, 6, 10, 12, 14}));
  EXPECT_EQ(Ids(by_default[0]), (std::set<int>{4, 5, 6, 7, 8, 9, 10, 12, 14}));
  EXPECT_EQ(Ids(small[0]), Ids(by_default[0]));
  const std::string weak = base + " --family tag16h5";
  EXPECT_EQ(RunCommand(weak, tmp.path() / "weak.json"), 0);  // the pass left out
  EXPECT_NE(RunCommand(weak + " --small-tags", tmp.path() / "weak_small.txt"), 0);
  EXPECT_NE(ReadText(tmp.path() / "weak_small.txt").find("tag16h5"), std::string::npos);
}

TEST(DetectCommand, AnUnreadableImageIsNamedAndTheOthersAreReported) {
  const auto good = testing::RecordingsDir() / "box_small" / "frames" / "000000.png";
  if (!std::filesystem::exists(good)) GTEST_SKIP() << "recordings/box_small is missing";
  TempDir tmp;
  const auto bad = tmp.path() / "truncated.png";
  std::ofstream(bad) << "\x89PNG\r\n";
  // stdout (the JSON) and stderr (the error) apart.
  const int status = std::system((testing::TagsfmExe().string() + " detect " + bad.string() + " " + good.string() +
                                  " > " + (tmp.path() / "out.json").string() + " 2> " + (tmp.path() / "err.txt").string())
                                     .c_str());
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_NE(WEXITSTATUS(status), 0);
  const std::string err = ReadText(tmp.path() / "err.txt");
  EXPECT_NE(err.find("truncated.png"), std::string::npos) << err;
  const auto out = ReadJsonFile(tmp.path() / "out.json");
  ASSERT_EQ(out.size(), 1u);
  EXPECT_EQ(out[0]["file"], good.string());
  EXPECT_GT(out[0]["tags"].size(), 3u);
}

// Median distance of the detected corners to the true ones (the bundled
// box_photos' ground truth projected through its camera), over the corners
// within 0.5 px (a partly occluded tag's are not the fit's).
double MedianCornerError(const nlohmann::json& images, const std::filesystem::path& rec, int* tags) {
  const auto reader = RecordingReader::Open(rec);
  const auto poses = ReadPosesCsv(rec / "ground_truth/poses.csv");
  const auto targets = ReadTargetsCsv(rec / "ground_truth/targets.csv");
  EXPECT_TRUE(reader && poses && targets);
  if (!reader || !poses || !targets) return NAN;
  const CameraModel& camera = *reader->info().camera;
  std::vector<double> errors;
  *tags = 0;
  for (size_t i = 0; i < images.size(); ++i) {
    const Rigid3d& cam_from_world = poses->at(reader->entries()[i].frame);
    for (const auto& tag : images[i]["tags"]) {
      ++*tags;
      const TagCorners& truth = targets->at(tag["id"].get<int>());
      for (size_t k = 0; k < 4; ++k) {
        const Eigen::Vector2d c(tag["corners"][k][0].get<double>(), tag["corners"][k][1].get<double>());
        const double e = (c - camera.Project(cam_from_world * truth[k])).norm();
        // The edge fit's covariance of every corner: positive definite, of
        // hundredths of a pixel (tests/detect/corner_covariance_test.cpp).
        const nlohmann::json& cov = tag["corner_covariance_px2"][k];
        EXPECT_TRUE(cov.is_array() && cov.size() == 3) << tag.dump();
        if (cov.is_array() && cov.size() == 3) {
          const double xx = cov[0], xy = cov[1], yy = cov[2];
          EXPECT_GT(xx * yy - xy * xy, 0.0) << tag.dump();
          EXPECT_LT(std::sqrt(0.5 * (xx + yy)), 0.2) << tag.dump();
        }
        if (e < 0.5) errors.push_back(e);
      }
    }
  }
  if (errors.empty()) return NAN;
  std::nth_element(errors.begin(), errors.begin() + errors.size() / 2, errors.end());
  return errors[errors.size() / 2];
}

// --camera FILE gives the edge fit the lens of a recording.yaml (or a run
// config's camera: block): on the bundled box_photos (k1 -0.12) the same tags,
// closer to the truth (docs/detection.md: median 0.034 -> 0.031 px). A file
// without a camera block, or an image of another size, is an error naming it.
TEST(DetectCommand, CameraFileGivesTheFitTheLens) {
  const auto rec = testing::RecordingsDir() / "box_photos";
  if (!std::filesystem::exists(rec / "recording.yaml")) GTEST_SKIP() << "recordings/box_photos is missing";
  const auto reader = RecordingReader::Open(rec);
  ASSERT_TRUE(reader) << reader.error().message;
  std::string images;
  for (const FrameEntry& entry : reader->entries()) images.append(" ").append(entry.file.string());
  TempDir tmp;
  std::string base = testing::TagsfmExe().string();
  base.append(" detect --no-small-tags").append(images);
  ASSERT_EQ(RunCommand(base, tmp.path() / "plain.json"), 0) << ReadText(tmp.path() / "plain.json");
  ASSERT_EQ(RunCommand(base + " --camera " + (rec / "recording.yaml").string(), tmp.path() / "lens.json"), 0)
      << ReadText(tmp.path() / "lens.json");
  const auto plain = ReadJsonFile(tmp.path() / "plain.json");
  const auto lens = ReadJsonFile(tmp.path() / "lens.json");
  ASSERT_EQ(plain.size(), reader->entries().size());
  ASSERT_EQ(lens.size(), plain.size());
  for (size_t i = 0; i < plain.size(); ++i) EXPECT_EQ(Ids(lens[i]), Ids(plain[i])) << "image " << i;
  int plain_tags = 0, lens_tags = 0;
  const double plain_median = MedianCornerError(plain, rec, &plain_tags);
  const double lens_median = MedianCornerError(lens, rec, &lens_tags);
  std::printf("box_photos, %d tags: median corner error %.4f px without the lens, %.4f with\n", plain_tags,
              plain_median, lens_median);
  EXPECT_GT(plain_tags, 40);
  EXPECT_LT(lens_median, plain_median);
  EXPECT_LT(lens_median, 0.05);

  // A YAML file with targets but no camera block; an image of another size.
  std::ofstream(tmp.path() / "no_camera.yaml") << "targets:\n  family: tag36h11\n  size_m: 0.06\n";
  EXPECT_EQ(RunCommand(base + " --camera " + (tmp.path() / "no_camera.yaml").string(), tmp.path() / "err1.txt"), 2);
  EXPECT_NE(ReadText(tmp.path() / "err1.txt").find("no camera"), std::string::npos) << ReadText(tmp.path() / "err1.txt");
  const auto other = testing::RecordingsDir() / "box_small" / "frames" / "000000.png";
  if (std::filesystem::exists(other)) {
    EXPECT_EQ(RunCommand(testing::TagsfmExe().string() + " detect " + other.string() + " --camera " +
                             (rec / "recording.yaml").string(),
                         tmp.path() / "err2.txt"),
              1);
    EXPECT_NE(ReadText(tmp.path() / "err2.txt").find("000000.png"), std::string::npos) << ReadText(tmp.path() / "err2.txt");
  }
}

}  // namespace
}  // namespace tagsfm
