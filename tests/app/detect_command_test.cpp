// tagsfm detect IMAGE...: JSON per image, the small-tag pass on request, and
// an unreadable image named while the others are still reported.
#include <sys/wait.h>

#include <cstdlib>
#include <fstream>
#include <set>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "run_command.h"
#include "test_paths.h"

namespace tagsfm {
namespace {

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
  const auto plain = nlohmann::json::parse(ReadText(tmp.path() / "plain.json"));
  const auto by_default = nlohmann::json::parse(ReadText(tmp.path() / "default.json"));
  const auto small = nlohmann::json::parse(ReadText(tmp.path() / "small.json"));
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
  const auto out = nlohmann::json::parse(ReadText(tmp.path() / "out.json"));
  ASSERT_EQ(out.size(), 1u);
  EXPECT_EQ(out[0]["file"], good.string());
  EXPECT_GT(out[0]["tags"].size(), 3u);
}

}  // namespace
}  // namespace tagsfm
