// Inputs ply_fuzz (fuzz/) found to crash eval's PLY reader, kept as
// regression tests: each is now an error naming the file, or reads as the
// format says.
#include <fstream>

#include <gtest/gtest.h>

#include "tagsfm/eval/ply_reader.h"
#include "test_paths.h"

namespace tagsfm::eval {
namespace {

// `text` written as cloud.ply in `tmp`; its path.
std::filesystem::path WritePly(const testing::TempDir& tmp, const std::string& text) {
  const auto path = tmp.path() / "cloud.ply";
  std::ofstream(path, std::ios::trunc) << text;
  return path;
}

TEST(FuzzFindings, PlyEndingAtEndHeaderWithoutNewlineIsNotACrash) {
  // end_header as the file's last bytes: the body offset was taken from a
  // failed tellg (-1) and substr threw std::out_of_range (abort).
  testing::TempDir tmp;
  const auto path = WritePly(tmp, "ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\n"
                                 "property float z\nend_header");
  auto empty = ReadPlyPoints(path);
  ASSERT_TRUE(empty.has_value()) << empty.error().message;
  EXPECT_TRUE(empty->empty());
  // With vertices promised and no body: an error naming the file.
  WritePly(tmp, "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
                "end_header");
  auto cut = ReadPlyPoints(path);
  ASSERT_FALSE(cut.has_value());
  EXPECT_NE(cut.error().message.find(path.string()), std::string::npos) << cut.error().message;
}

TEST(FuzzFindings, PlyClaimingAHugeVertexCountIsAnErrorNotAnAllocation) {
  // The header's count went straight to reserve(): 10^18 vertices threw
  // std::length_error (or ran out of memory) before a byte was read.
  testing::TempDir tmp;
  const auto path = WritePly(tmp, "ply\nformat ascii 1.0\nelement vertex 1000000000000000000\nproperty float x\n"
                                 "property float y\nproperty float z\nend_header\n0 0 0\n");
  auto points = ReadPlyPoints(path);
  ASSERT_FALSE(points.has_value());
  EXPECT_NE(points.error().message.find(path.string()), std::string::npos) << points.error().message;
}

TEST(FuzzFindings, PlyListCountOfFloatTypeOutOfRangeIsAnError) {
  // A list whose count type is float, holding 7e22: the cast of the count
  // to long long was undefined (UBSan).
  testing::TempDir tmp;
  const auto path = WritePly(tmp, "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
                                 "property float z\nproperty list float int extra\nend_header\n0 0 0 7e22 1 2\n");
  auto points = ReadPlyPoints(path);
  ASSERT_FALSE(points.has_value());
  EXPECT_NE(points.error().message.find("extra"), std::string::npos) << points.error().message;
}

TEST(FuzzFindings, PlyElementWithoutPropertiesAndAHugeCountIsSkippedNotLoopedOver) {
  // An element with no properties claiming 2.5 * 10^15 items: the reader
  // looped over them reading nothing (a libFuzzer timeout, 2026-12-04).
  testing::TempDir tmp;
  const auto path = WritePly(tmp, "ply\nformat ascii 1.0\nelement face 2544444444444444\nelement vertex 1\nproperty float x\n"
                                 "property float y\nproperty float z\nend_header\n1 2 3\n");
  auto points = ReadPlyPoints(path);
  ASSERT_TRUE(points.has_value()) << points.error().message;
  ASSERT_EQ(points->size(), 1u);
  EXPECT_EQ((*points)[0], Eigen::Vector3d(1, 2, 3));
}

}  // namespace
}  // namespace tagsfm::eval
