// Reading COLMAP text models, and scoring one against a recording's truth
// as `tagsfm evaluate` does (bench/compare_colmap.sh relies on both).
#include <gtest/gtest.h>

#include <cmath>

#include <nlohmann/json.hpp>

#include "tagsfm/core/csv_formats.h"
#include "tagsfm/core/file_util.h"
#include "tagsfm/eval/colmap_model.h"
#include "tagsfm/eval/evaluation.h"
#include "test_paths.h"

namespace tagsfm::eval {
namespace {

namespace fs = std::filesystem;
constexpr double kDeg = M_PI / 180;

const char* kCameras =
    "# Camera list with one line of data per camera:\n"
    "#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n"
    "# Number of cameras: 1\n"
    "1 PINHOLE 640 480 500 500 320 240\n";

// Two images, the second without keypoints (an empty POINTS2D line).
const char* kImages =
    "# Image list with two lines of data per image:\n"
    "# Number of images: 2, mean observations per image: 1\n"
    "7 0.5 0.5 0.5 0.5 1 2 3 1 frames/000000.png\n"
    "10.5 20.5 4 30 40 -1\n"
    "9 2 0 0 0 -1 0 0.5 1 frames/000001.png\n"
    "\n";

const char* kPoints =
    "# 3D point list with one line of data per point:\n"
    "# Number of points: 2, mean track length: 1.5\n"
    "4 0.25 -1 2 255 0 10 0.75 7 0 9 3\n"
    "5 1 1 1 1 2 3 0.5 7 1\n";

void Write(const fs::path& path, const std::string& text) { ASSERT_TRUE(WriteFileAtomically(path, text)); }

TEST(ColmapModel, ReadsCamerasImagesByNameAndPoints) {
  tagsfm::testing::TempDir dir;
  Write(dir.path() / "cameras.txt", kCameras);
  Write(dir.path() / "images.txt", kImages);
  Write(dir.path() / "points3D.txt", kPoints);
  ASSERT_TRUE(IsColmapTextModel(dir.path()));
  Result<ColmapModel> model = ReadColmapTextModel(dir.path());
  ASSERT_TRUE(model) << model.error().message;
  ASSERT_EQ(model->cameras.size(), 1u);
  EXPECT_EQ(model->cameras.at(1).model, "PINHOLE");
  EXPECT_EQ(model->cameras.at(1).params, (std::vector<double>{500, 500, 320, 240}));
  ASSERT_EQ(model->images_by_name.size(), 2u);
  const ColmapImage& a = model->images_by_name.at("frames/000000.png");
  EXPECT_EQ(a.id, 7);
  EXPECT_EQ(a.points2d, 2);
  EXPECT_EQ(a.observed_points2d, 1);
  // World-to-camera, QW QX QY QZ: (0.5, 0.5, 0.5, 0.5) turns x to y, y to z.
  EXPECT_NEAR((a.cam_from_world.rotation * Eigen::Vector3d::UnitX() - Eigen::Vector3d::UnitY()).norm(), 0, 1e-12);
  EXPECT_EQ(a.cam_from_world.translation, Eigen::Vector3d(1, 2, 3));
  const ColmapImage& b = model->images_by_name.at("frames/000001.png");
  EXPECT_EQ(b.points2d, 0);
  // An unnormalised quaternion is normalised: (2, 0, 0, 0) is the identity.
  EXPECT_NEAR(b.cam_from_world.rotation.w(), 1.0, 1e-12);
  EXPECT_NEAR((b.cam_from_world.Center() - Eigen::Vector3d(1, 0, -0.5)).norm(), 0, 1e-12);
  ASSERT_EQ(model->points.size(), 2u);
  EXPECT_EQ(model->points[0].id, 4);
  EXPECT_EQ(model->points[0].xyz, Eigen::Vector3d(0.25, -1, 2));
  EXPECT_DOUBLE_EQ(model->points[0].error_px, 0.75);
  EXPECT_EQ(model->points[0].track_length, 2);
  EXPECT_EQ(model->points[1].track_length, 1);
}

// Each bad file is one error naming the file, and the line where there is one.
TEST(ColmapModel, MalformedOrTruncatedFilesNameFileAndLine) {
  tagsfm::testing::TempDir dir;
  const fs::path images = dir.path() / "images.txt", points = dir.path() / "points3D.txt",
                 cameras = dir.path() / "cameras.txt";
  struct Case {
    fs::path file;
    std::string text, expected;
  };
  const std::vector<Case> cases = {
      // Cut after an image's first line: its POINTS2D line is missing.
      {images, "# Number of images: 1\n7 1 0 0 0 1 2 3 1 a.png\n", ":2: image 7 has no POINTS2D line"},
      // Cut in the middle of a first line.
      {images, "7 1 0 0 0 1 2", ":1: expected IMAGE_ID"},
      {images, "7 1 0 zero 0 1 2 3 1 a.png\n\n", ":1: QY is not a number"},
      {images, "7 1 0 0 0 1 2 3 1 a.png\n1 2\n", ":2: POINTS2D must be triples"},
      {images, "7 1 0 0 0 1 2 3 1 a.png\n\n8 1 0 0 0 1 2 3 1 a.png\n\n", ":3: image name 'a.png' listed twice"},
      // Cut in a track, and cut at a line boundary (the header's count tells).
      {points, "4 0.25 -1 2 255 0 10 0.75 7 0 9\n", ":1: TRACK must be pairs"},
      {points, "# Number of points: 3, mean track length: 2\n4 0 0 0 1 1 1 0.5 1 0\n", "the header says 3 points, the file has 1"},
      {points, "4 0 0 0 1 1 1 -0.5 1 0\n", ":1: ERROR '-0.5'"},
      {points, "4 0 0 0 1 1 1\n", ":1: expected POINT3D_ID"},
      {cameras, "# c\n1 PINHOLE 640 480 500 x 320 240\n", ":2: parameter 2 'x' is not a number"},
  };
  for (const Case& c : cases) {
    Write(cameras, kCameras);
    Write(images, kImages);
    Write(points, kPoints);
    Write(c.file, c.text);
    Result<ColmapModel> model = ReadColmapTextModel(dir.path());
    ASSERT_FALSE(model) << c.text;
    EXPECT_NE(model.error().message.find(c.file.string() + (c.expected[0] == ':' ? "" : ": ") + c.expected),
              std::string::npos)
        << model.error().message;
    EXPECT_EQ(model.error().message.find('\n'), std::string::npos);
  }
  // An image naming a camera cameras.txt lacks.
  Write(cameras, "2 PINHOLE 640 480 500 500 320 240\n");
  Write(images, kImages);
  Result<ColmapModel> model = ReadColmapTextModel(dir.path());
  ASSERT_FALSE(model);
  EXPECT_NE(model.error().message.find("names camera 1, which cameras.txt lacks"), std::string::npos);
}

// A recording with five true frames looking at a wall (the plane y = 0).
PoseMap FivePoses() {
  PoseMap poses;
  for (int f = 0; f < 5; ++f) {
    Eigen::Matrix3d looking_along_y;
    looking_along_y << 1, 0, 0, 0, 0, -1, 0, 1, 0;
    const Eigen::Quaterniond yaw(Eigen::AngleAxisd((f - 2) * 10 * kDeg, Eigen::Vector3d::UnitZ()));
    const Eigen::Quaterniond cam_from_world = Eigen::Quaterniond(looking_along_y) * yaw.conjugate();
    const Eigen::Vector3d centre = yaw * Eigen::Vector3d(0, -2.0, 0) + Eigen::Vector3d(0, 0, 1.05);
    poses[f] = Rigid3d(cam_from_world, -(cam_from_world * centre));
  }
  return poses;
}

void WriteRecording(const fs::path& rec, const PoseMap& poses) {
  fs::create_directories(rec / "frames");
  fs::create_directories(rec / "ground_truth");
  Write(rec / "recording.yaml",
        "format: tagsfm-recording/1\ncamera:\n  width: 640\n  height: 480\n  fx: 500\n  fy: 500\n  cx: 319.5\n"
        "  cy: 239.5\n  distortion: []\ntargets:\n  family: tag36h11\n  size_m: 0.06\n");
  std::string frames = "frame,timestamp_ns,file\n";
  for (const auto& [f, pose] : poses) {
    const std::string name = "frames/00000" + std::to_string(f) + ".png";
    frames += std::to_string(f) + "," + std::to_string(f * 1000) + "," + name + "\n";
    Write(rec / name, "not decoded by evaluate");
  }
  Write(rec / "frames.csv", frames);
  ASSERT_TRUE(WritePosesCsv(rec / "ground_truth" / "poses.csv", poses));
  Write(rec / "ground_truth" / "scene.yaml",
        "format: tagsfm-synth-scene/1\nfaces:\n  - name: wall\n    origin: [-2, 0, 0]\n    edge_u: [4, 0, 0]\n"
        "    edge_v: [0, 0, 2.5]\n");
}

// True points off the wall by known distances (along its normal, y), and the
// reprojection errors the files give them.
const std::vector<double> kOffsets = {0.0005, 0.0015, -0.003, 0.010, 0.0049};
const std::vector<double> kErrors = {0.1, 0.2, 0.3, 0.4, 0.5};
Eigen::Vector3d TruePoint(size_t i) { return Eigen::Vector3d(-0.5 + 0.25 * static_cast<double>(i), kOffsets[i], 1.2); }

nlohmann::json EvaluateJson(const fs::path& out, const fs::path& rec) {
  Result<std::string> text = EvaluateDirectoriesJson(out, rec);
  EXPECT_TRUE(text) << text.error().message;
  return text ? nlohmann::json::parse(*text) : nlohmann::json();
}

// COLMAP's model lives in its own frame and unit: x_true = s R x_colmap + t.
TEST(EvaluateColmapModel, RegisteredFramesSharesAndScaleAfterTheSimilarityFit) {
  tagsfm::testing::TempDir dir;
  const fs::path rec = dir.path() / "rec", model = dir.path() / "model";
  const PoseMap truth = FivePoses();
  WriteRecording(rec, truth);
  const double s = 2.0;
  const Eigen::Quaterniond r(Eigen::AngleAxisd(30 * kDeg, Eigen::Vector3d(0.2, 0.3, 1).normalized()));
  const Eigen::Vector3d t(0.3, -0.2, 0.1);
  const auto to_colmap = [&](const Eigen::Vector3d& x) -> Eigen::Vector3d { return r.conjugate() * (x - t) / s; };
  // Frames 0-3 registered (two by the path relative to REC, two by the bare
  // file name), frame 4 not; one image no frame has.
  std::string images = "# Number of images: 5, mean observations per image: 0\n";
  const auto add_image = [&](int id, const Rigid3d& cam_from_true, const std::string& name) {
    const Eigen::Quaterniond q = cam_from_true.rotation * r;
    const Eigen::Vector3d tr = (cam_from_true.rotation * t + cam_from_true.translation) / s;
    char line[512];
    std::snprintf(line, sizeof(line), "%d %.17g %.17g %.17g %.17g %.17g %.17g %.17g 1 %s\n\n", id, q.w(), q.x(), q.y(),
                  q.z(), tr.x(), tr.y(), tr.z(), name.c_str());
    images += line;
  };
  add_image(1, truth.at(0), "frames/000000.png");
  add_image(2, truth.at(1), "frames/000001.png");
  add_image(3, truth.at(2), "000002.png");
  add_image(4, truth.at(3), "000003.png");
  add_image(5, truth.at(4) * Rigid3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(5, 0, 0)), "other/x.png");
  std::string points;
  for (size_t i = 0; i < kOffsets.size(); ++i) {
    const Eigen::Vector3d p = to_colmap(TruePoint(i));
    char line[256];
    std::snprintf(line, sizeof(line), "%zu %.17g %.17g %.17g 1 2 3 %.17g 1 0 2 0\n", i + 1, p.x(), p.y(), p.z(), kErrors[i]);
    points += line;
  }
  fs::create_directories(model);
  Write(model / "cameras.txt", kCameras);
  Write(model / "images.txt", images);
  Write(model / "points3D.txt", points);

  const nlohmann::json e = EvaluateJson(model, rec);
  ASSERT_TRUE(e.is_object());
  EXPECT_EQ(e["result_format"], "colmap_text");
  EXPECT_EQ(e["frames"]["ground_truth"], 5);
  EXPECT_EQ(e["frames"]["registered"], 4);
  EXPECT_EQ(e["files"]["result"]["colmap_images_not_in_frames_csv"], nlohmann::json::array({"other/x.png"}));
  EXPECT_EQ(e["alignment"]["source"], "camera_centres");
  EXPECT_EQ(e["alignment"]["correspondences"], 4);
  EXPECT_NEAR(e["alignment"]["similarity"]["scale_error_ppm"].get<double>(), (s - 1) * 1e6, 1e-3);
  EXPECT_NEAR(e["alignment"]["similarity"]["rotation_deg"].get<double>(), 30, 1e-6);
  EXPECT_EQ(e["cloud_points"], 5);
  EXPECT_EQ(e["feature_points"]["count"], 5);
  EXPECT_EQ(e["feature_points"]["source"], "points3D.txt");
  EXPECT_NEAR(e["feature_points"]["mean_reprojection_px"].get<double>(), 0.3, 1e-12);
  const nlohmann::json& sim = e["similarity"];
  EXPECT_LT(sim["poses"]["position_m"]["max"].get<double>(), 1e-9);
  EXPECT_DOUBLE_EQ(sim["feature_points"]["within_1mm"].get<double>(), 1.0 / 5);
  EXPECT_DOUBLE_EQ(sim["feature_points"]["within_2mm"].get<double>(), 2.0 / 5);
  EXPECT_DOUBLE_EQ(sim["feature_points"]["within_5mm"].get<double>(), 4.0 / 5);
  EXPECT_NEAR(sim["feature_points"]["distance_m"]["max"].get<double>(), 0.010, 1e-9);
  EXPECT_NEAR(sim["cloud_distance_m"]["median"].get<double>(), 0.003, 1e-9);
  // As it is, COLMAP's frame is not the true one: the points are far off.
  EXPECT_LT(e["as_is"]["feature_points"]["within_5mm"].get<double>(), 0.5);
}

// A tagsfm result: the feature points are features.csv's, scored apart
// from cloud.ply (which also holds the target corners).
TEST(EvaluateColmapModel, TagsfmFeaturePointsAreScoredFromFeaturesCsv) {
  tagsfm::testing::TempDir dir;
  const fs::path rec = dir.path() / "rec", out = dir.path() / "out";
  const PoseMap truth = FivePoses();
  WriteRecording(rec, truth);
  fs::create_directories(out);
  ASSERT_TRUE(WritePosesCsv(out / "poses.csv", truth));
  std::string features = "point_id,x,y,z,r,g,b,track_length,reprojection_rms_px,cov_xx,cov_xy,cov_xz,cov_yy,cov_yz,cov_zz\n";
  for (size_t i = 0; i < 3; ++i) {
    const Eigen::Vector3d p = TruePoint(i);
    features += std::to_string(1000 + i) + "," + std::to_string(p.x()) + "," + std::to_string(p.y()) + "," +
                std::to_string(p.z()) + ",1,2,3,2," + std::to_string(kErrors[i]) + ",1,0,0,1,0,1\n";
  }
  Write(out / "features.csv", features);
  const nlohmann::json e = EvaluateJson(out, rec);
  ASSERT_TRUE(e.is_object());
  EXPECT_EQ(e["result_format"], "tagsfm");
  EXPECT_EQ(e["frames"]["registered"], 5);
  EXPECT_EQ(e["feature_points"]["count"], 3);
  EXPECT_EQ(e["feature_points"]["source"], "features.csv");
  EXPECT_NEAR(e["feature_points"]["mean_reprojection_px"].get<double>(), 0.2, 1e-12);
  EXPECT_EQ(e["cloud_points"], 0);  // no cloud.ply
  EXPECT_TRUE(e["as_is"]["cloud_distance_m"].is_null());
  EXPECT_DOUBLE_EQ(e["as_is"]["feature_points"]["within_1mm"].get<double>(), 1.0 / 3);
  EXPECT_DOUBLE_EQ(e["as_is"]["feature_points"]["within_2mm"].get<double>(), 2.0 / 3);
  EXPECT_DOUBLE_EQ(e["as_is"]["feature_points"]["within_5mm"].get<double>(), 1.0);
  EXPECT_NEAR(e["alignment"]["similarity"]["scale_error_ppm"].get<double>(), 0, 1e-3);
}

TEST(EvaluateColmapModel, ATruncatedModelIsAnErrorNamingTheFile) {
  tagsfm::testing::TempDir dir;
  const fs::path rec = dir.path() / "rec", model = dir.path() / "model";
  WriteRecording(rec, FivePoses());
  fs::create_directories(model);
  Write(model / "images.txt", "1 1 0 0 0 0 0 0 1 frames/000000.png\n");
  Write(model / "points3D.txt", "");
  Result<std::string> text = EvaluateDirectoriesJson(model, rec);
  ASSERT_FALSE(text);
  EXPECT_NE(text.error().message.find((model / "images.txt").string() + ":1:"), std::string::npos)
      << text.error().message;
}

}  // namespace
}  // namespace tagsfm::eval
