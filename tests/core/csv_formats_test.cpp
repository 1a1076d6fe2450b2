#include "tagsfm/core/csv_formats.h"

#include <fstream>

#include <gtest/gtest.h>

#include "tagsfm/core/file_util.h"
#include "test_paths.h"

namespace tagsfm {
namespace {

using testing::TempDir;

void WriteText(const std::filesystem::path& path, const std::string& text) {
  std::ofstream(path) << text;
}

TEST(CsvFormats, TargetsRoundTripExactly) {
  TempDir tmp;
  TargetCornerMap targets;
  targets[3] = {Eigen::Vector3d(0.1, 0.2, 0.3), Eigen::Vector3d(1.0 / 3.0, 0, 0), Eigen::Vector3d(0, 1e-9, 0),
                Eigen::Vector3d(-5, 6, 7.123456789012345)};
  targets[17] = {Eigen::Vector3d(1, 1, 1), Eigen::Vector3d(2, 2, 2), Eigen::Vector3d(3, 3, 3), Eigen::Vector3d(4, 4, 4)};
  ASSERT_TRUE(WriteTargetsCsv(tmp.path() / "targets.csv", targets));
  auto read = ReadTargetsCsv(tmp.path() / "targets.csv");
  ASSERT_TRUE(read) << read.error().message;
  ASSERT_EQ(read->size(), 2u);
  for (const auto& [id, corners] : targets) {
    for (int c = 0; c < 4; ++c) EXPECT_EQ(read->at(id)[c], corners[c]);  // %.17g round-trips doubles
  }
}

TEST(CsvFormats, PosesRoundTripExactly) {
  TempDir tmp;
  PoseMap poses;
  poses[0] = Rigid3d(Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 2, 3).normalized())),
                     Eigen::Vector3d(0.1, -0.2, 2.5));
  poses[42] = Rigid3d();
  ASSERT_TRUE(WritePosesCsv(tmp.path() / "poses.csv", poses));
  auto read = ReadPosesCsv(tmp.path() / "poses.csv");
  ASSERT_TRUE(read) << read.error().message;
  ASSERT_EQ(read->size(), 2u);
  EXPECT_LT(RotationAngleDeg(read->at(0).rotation, poses[0].rotation), 1e-9);
  EXPECT_EQ(read->at(0).translation, poses[0].translation);
}

TEST(CsvFormats, ErrorsNameFileLineAndField) {
  TempDir tmp;
  const auto path = tmp.path() / "targets.csv";
  WriteText(path, "tag_id,corner,x,y,z\n1,0,0,0,0\n1,1,0,abc,0\n");
  auto read = ReadTargetsCsv(path);
  ASSERT_FALSE(read);
  EXPECT_NE(read.error().message.find("targets.csv:3"), std::string::npos) << read.error().message;
  EXPECT_NE(read.error().message.find("'y'"), std::string::npos) << read.error().message;

  WriteText(path, "tag_id,corner,x,y,z\n1,0,0,0,0\n1,1,0,0,0\n1,2,0,0,0\n");
  read = ReadTargetsCsv(path);
  ASSERT_FALSE(read);
  EXPECT_NE(read.error().message.find("lacks corner 3"), std::string::npos) << read.error().message;

  WriteText(path, "id,corner,x,y,z\n");
  EXPECT_FALSE(ReadTargetsCsv(path));
  EXPECT_FALSE(ReadTargetsCsv(tmp.path() / "missing.csv"));

  const auto poses = tmp.path() / "poses.csv";
  WriteText(poses, "frame,qw,qx,qy,qz,tx,ty,tz\n0,2,0,0,0,0,0,0\n");
  auto read_poses = ReadPosesCsv(poses);
  ASSERT_FALSE(read_poses);
  EXPECT_NE(read_poses.error().message.find("unit length"), std::string::npos);
}

TEST(FileUtil, AtomicWriteLeavesNoTemporary) {
  TempDir tmp;
  const auto path = tmp.path() / "a.txt";
  ASSERT_TRUE(WriteFileAtomically(path, std::string("first")));
  ASSERT_TRUE(WriteFileAtomically(path, std::string("second")));
  EXPECT_EQ(*ReadFileToString(path), "second");
  EXPECT_FALSE(std::filesystem::exists(path.string() + ".tmp"));
  EXPECT_FALSE(WriteFileAtomically(tmp.path() / "no_such_dir" / "a.txt", std::string("x")));
}

TEST(FileUtil, ParseNumbersRejectsGarbage) {
  double d = 0;
  long long i = 0;
  EXPECT_TRUE(ParseDouble(" 1.5e-3 ", &d));
  EXPECT_DOUBLE_EQ(d, 1.5e-3);
  EXPECT_FALSE(ParseDouble("1.5x", &d));
  EXPECT_FALSE(ParseDouble("", &d));
  EXPECT_TRUE(ParseInt64("-42", &i));
  EXPECT_EQ(i, -42);
  EXPECT_FALSE(ParseInt64("4.2", &i));
}

}  // namespace
}  // namespace tagsfm
