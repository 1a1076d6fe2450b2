// Reading the result files: PLY in its variants, scene.yaml, and the
// directory-level evaluation (absent files are reported, bad ones named).
#include <gtest/gtest.h>

#include <cstring>
#include <fstream>

#include <nlohmann/json.hpp>

#include "tagsfm/core/csv_formats.h"
#include "tagsfm/core/file_util.h"
#include "tagsfm/eval/evaluation.h"
#include "tagsfm/eval/ply_reader.h"
#include "tagsfm/eval/scene_geometry.h"
#include "test_paths.h"

namespace tagsfm::eval {
namespace {

namespace fs = std::filesystem;

template <class T>
void Append(std::string* bytes, T value) {
  char raw[sizeof(T)];
  std::memcpy(raw, &value, sizeof(T));
  bytes->append(raw, sizeof(T));
}

// The layout the reconstruction writes.
std::string BinaryCloud(int points, bool truncate) {
  std::string ply =
      "ply\nformat binary_little_endian 1.0\ncomment test\nelement vertex " + std::to_string(points) +
      "\nproperty double x\nproperty double y\nproperty double z\nproperty uchar red\nproperty uchar green\n"
      "property uchar blue\nproperty int track_length\nproperty float reprojection_error\nend_header\n";
  for (int i = 0; i < points; ++i) {
    Append(&ply, 0.5 * i);
    Append(&ply, -1.0 * i);
    Append(&ply, 2.0);
    for (int c = 0; c < 3; ++c) Append(&ply, static_cast<unsigned char>(200));
    Append(&ply, 3);
    Append(&ply, 0.25f);
  }
  if (truncate) ply.resize(ply.size() - 5);
  return ply;
}

TEST(PlyReader, ReadsTheBinaryLayoutOfCloudPly) {
  tagsfm::testing::TempDir dir;
  ASSERT_TRUE(WriteFileAtomically(dir.path() / "cloud.ply", BinaryCloud(3, false)));
  Result<std::vector<Eigen::Vector3d>> points = ReadPlyPoints(dir.path() / "cloud.ply");
  ASSERT_TRUE(points) << points.error().message;
  ASSERT_EQ(points->size(), 3u);
  EXPECT_EQ((*points)[2], Eigen::Vector3d(1.0, -2.0, 2.0));
}

TEST(PlyReader, ReadsAsciiInAnyPropertyOrderWithOtherElements) {
  tagsfm::testing::TempDir dir;
  const std::string ply =
      "ply\nformat ascii 1.0\nelement camera 1\nproperty list uchar int ids\nproperty float f\n"
      "element vertex 2\nproperty float z\nproperty uchar red\nproperty float x\nproperty float y\n"
      "element face 0\nproperty list uchar int vertex_indices\nend_header\n"
      "3 1 2 3 0.5\n1.5 9 2.5 3.5\n-1 9 -2 -3\n";
  ASSERT_TRUE(WriteFileAtomically(dir.path() / "a.ply", ply));
  Result<std::vector<Eigen::Vector3d>> points = ReadPlyPoints(dir.path() / "a.ply");
  ASSERT_TRUE(points) << points.error().message;
  ASSERT_EQ(points->size(), 2u);
  EXPECT_EQ((*points)[0], Eigen::Vector3d(2.5, 3.5, 1.5));
  EXPECT_EQ((*points)[1], Eigen::Vector3d(-2, -3, -1));
}

TEST(PlyReader, TruncatedOrMalformedFilesAreNamedErrors) {
  tagsfm::testing::TempDir dir;
  const fs::path file = dir.path() / "cloud.ply";
  ASSERT_TRUE(WriteFileAtomically(file, BinaryCloud(4, true)));
  Result<std::vector<Eigen::Vector3d>> points = ReadPlyPoints(file);
  ASSERT_FALSE(points);
  EXPECT_NE(points.error().message.find(file.string()), std::string::npos) << points.error().message;
  EXPECT_NE(points.error().message.find("vertex 3"), std::string::npos) << points.error().message;
  for (const std::string& bad : {std::string("not a ply"), std::string("ply\nformat ascii 1.0\nelement vertex 1\n"),
                                std::string("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\n1\n"),
                                std::string("ply\nformat weird 1.0\nend_header\n")}) {
    ASSERT_TRUE(WriteFileAtomically(file, bad));
    EXPECT_FALSE(ReadPlyPoints(file)) << bad;
  }
}

TEST(SceneYaml, ReadsRectanglesAndNamesBadFields) {
  tagsfm::testing::TempDir dir;
  const fs::path file = dir.path() / "scene.yaml";
  ASSERT_TRUE(WriteFileAtomically(file, "faces:\n  - {name: wall, origin: [-2, 0, 0], edge_u: [4, 0, 0], edge_v: [0, 0, 2.5]}\n"));
  Result<std::vector<SurfaceRectangle>> surfaces = ReadSceneYaml(file);
  ASSERT_TRUE(surfaces) << surfaces.error().message;
  ASSERT_EQ(surfaces->size(), 1u);
  EXPECT_DOUBLE_EQ(DistanceToSurfaces(*surfaces, {0.5, -0.3, 1}), 0.3);
  ASSERT_TRUE(WriteFileAtomically(file, "faces:\n  - {origin: [0, 0], edge_u: [4, 0, 0], edge_v: [0, 0, 2.5]}\n"));
  surfaces = ReadSceneYaml(file);
  ASSERT_FALSE(surfaces);
  EXPECT_NE(surfaces.error().message.find("faces[0].origin"), std::string::npos) << surfaces.error().message;
}

// A minimal recording with ground truth, and a result that is the truth.
void MakeRecordingAndResult(const fs::path& rec, const fs::path& out) {
  fs::create_directories(rec / "ground_truth");
  fs::create_directories(out);
  ASSERT_TRUE(WriteFileAtomically(rec / "recording.yaml",
                                  "format: tagsfm-recording/1\ncamera: {width: 640, height: 480, fx: 500, fy: 500, "
                                  "cx: 319.5, cy: 239.5}\ntargets: {family: tag36h11, size_m: 0.06}\n"));
  PoseMap poses;
  poses[0] = Rigid3d(Eigen::Quaterniond::Identity(), {0, 0, 2});
  poses[1] = Rigid3d(Eigen::Quaterniond::Identity(), {0.2, 0, 2});
  TargetCornerMap targets;
  targets[3] = {Eigen::Vector3d(0, 0, 0), {0.06, 0, 0}, {0.06, 0.06, 0}, {0, 0.06, 0}};
  ASSERT_TRUE(WritePosesCsv(rec / "ground_truth/poses.csv", poses));
  ASSERT_TRUE(WriteTargetsCsv(rec / "ground_truth/targets.csv", targets));
  ASSERT_TRUE(WritePosesCsv(out / "poses.csv", poses));
}

TEST(EvaluateDirectories, AbsentFilesAreReportedNotErrors) {
  tagsfm::testing::TempDir dir;
  MakeRecordingAndResult(dir.path() / "rec", dir.path() / "out");
  Result<std::string> text = EvaluateDirectoriesJson(dir.path() / "out", dir.path() / "rec");
  ASSERT_TRUE(text) << text.error().message;
  const nlohmann::json j = nlohmann::json::parse(*text);
  EXPECT_EQ(j["files"]["result"]["poses.csv"], true);
  EXPECT_EQ(j["files"]["result"]["cloud.ply"], false);
  EXPECT_EQ(j["files"]["result"]["report.json"], false);
  EXPECT_EQ(j["files"]["ground_truth"]["scene.yaml"], false);
  EXPECT_EQ(j["frames"]["registered"], 2);
  EXPECT_EQ(j["as_is"]["poses"]["position_m"]["max"], 0.0);
  EXPECT_TRUE(j["as_is"]["cloud_distance_m"].is_null());
  EXPECT_EQ(j["alignment"]["source"], "none");  // 2 cameras, no estimated targets: nothing to align on
  EXPECT_TRUE(j["similarity"].is_null());
}

TEST(EvaluateDirectories, MalformedFilesAreOneLineErrorsNamingThem) {
  tagsfm::testing::TempDir dir;
  MakeRecordingAndResult(dir.path() / "rec", dir.path() / "out");
  ASSERT_TRUE(WriteFileAtomically(dir.path() / "out/report.json", "{\"frames\": 3"));
  Result<std::string> text = EvaluateDirectoriesJson(dir.path() / "out", dir.path() / "rec");
  ASSERT_FALSE(text);
  EXPECT_NE(text.error().message.find("report.json"), std::string::npos) << text.error().message;
  fs::remove(dir.path() / "out/report.json");
  ASSERT_TRUE(WriteFileAtomically(dir.path() / "out/poses.csv", "frame,qw,qx,qy,qz,tx,ty,tz\n0,1,0,0,zero,0,0,2\n"));
  text = EvaluateDirectoriesJson(dir.path() / "out", dir.path() / "rec");
  ASSERT_FALSE(text);
  EXPECT_NE(text.error().message.find("poses.csv"), std::string::npos) << text.error().message;
  EXPECT_EQ(text.error().message.find('\n'), std::string::npos);
  fs::remove_all(dir.path() / "rec/ground_truth");
  text = EvaluateDirectoriesJson(dir.path() / "out", dir.path() / "rec");
  ASSERT_FALSE(text);
  EXPECT_NE(text.error().message.find("ground_truth"), std::string::npos) << text.error().message;
}

}  // namespace
}  // namespace tagsfm::eval
