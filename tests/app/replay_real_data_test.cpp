// The reconstruction on real photos (../shared/data), each set turned into a
// recording in a temporary folder: recording.yaml + frames.csv naming the
// images where they are. Figures are printed for the notes; bounds are
// regression checks at about 1.5-2x what was measured (2026-11-22).
#include <algorithm>
#include <cmath>
#include <fstream>
#include <iostream>
#include <sstream>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "tagsfm/core/file_util.h"

#include "tagsfm/capture/recording.h"
#include "tagsfm/detect/tag_detector.h"
#include "tagsfm/recon/bundle_adjuster.h"
#include "tagsfm/recon/reconstructor.h"
#include "tagsfm/recon/tag_geometry.h"
#include "test_paths.h"

namespace tagsfm {
namespace {

namespace fs = std::filesystem;
using testing::SharedDataDir;
using testing::TempDir;

fs::path MakeRecording(const fs::path& dir, const std::string& camera_yaml, double tag_size,
                       const std::vector<fs::path>& images) {
  std::ofstream(dir / "recording.yaml") << "format: tagsfm-recording/1\ncamera: " << camera_yaml
                                        << "\ntargets: {family: tag36h11, size_m: " << tag_size << "}\n";
  std::ofstream frames(dir / "frames.csv");
  frames << "frame,timestamp_ns,file\n";
  for (size_t i = 0; i < images.size(); ++i) frames << i << "," << i * 33333333 << "," << images[i].string() << "\n";
  return dir;
}

std::vector<fs::path> ImagesIn(const fs::path& dir, const std::string& extension) {
  std::vector<fs::path> images;
  for (const auto& entry : fs::directory_iterator(dir)) {
    if (entry.path().extension() == extension) images.push_back(entry.path());
  }
  std::sort(images.begin(), images.end());
  return images;
}

// Detect and reconstruct every frame of a recording, as replay does.
ReconstructionResult Reconstruct(const fs::path& rec_dir) {
  auto reader = RecordingReader::Open(rec_dir);
  EXPECT_TRUE(reader.has_value()) << (reader ? "" : reader.error().message);
  TagDetectorOptions detector_options;
  auto detector = TagDetector::Create(detector_options);
  EXPECT_TRUE(detector.has_value());
  auto recon = Reconstructor::Create(*reader->info().camera, reader->info().targets, std::nullopt, {});
  EXPECT_TRUE(recon.has_value());
  for (size_t i = 0; i < reader->entries().size(); ++i) {
    auto frame = reader->LoadFrame(i);
    EXPECT_TRUE(frame.has_value());
    if (!frame) continue;
    auto detections = (*detector)->Detect(frame->gray, frame->index);
    EXPECT_TRUE(detections.has_value());
    if (detections) (*recon)->AddFrame(*detections);
  }
  return (*recon)->Finish();
}

double FrameRmsPx(const ReconstructionResult& result, const FrameState& frame) {
  double sum = 0;
  int n = 0;
  for (const auto& obs : frame.tags) {
    auto it = result.tags.find(obs.id);
    if (it == result.tags.end()) continue;
    const TagCorners corners = it->second.CornersInWorld();
    for (int k = 0; k < 4; ++k) {
      sum += (result.camera.Project(frame.cam_from_world.ToRigid() * corners[k]) - obs.pixels[k]).squaredNorm();
      ++n;
    }
  }
  return n ? std::sqrt(sum / n) : INFINITY;
}

TEST(ReplayRealDataSlow, SwatboticsRoomLoop) {
  TAGSFM_REQUIRE_SHARED_DATA("swatbotics-mapping/images/mapping_feb_2014");
  TempDir scratch;
  const auto images = ImagesIn(SharedDataDir() / "swatbotics-mapping/images/mapping_feb_2014", ".JPG");
  ASSERT_EQ(images.size(), 72u);
  const ReconstructionResult result = Reconstruct(MakeRecording(
      scratch.path(), "{width: 816, height: 612, fx: 765.00, fy: 764.18, cx: 393.72, cy: 304.66, distortion: []}",
      0.127, images));
  int registered = 0, with_tags = 0;
  for (const auto& f : result.frames) {
    registered += f.registered;
    with_tags += !f.tags.empty();
  }
  const double first_rms = FrameRmsPx(result, result.frames.front());
  const double last_rms = FrameRmsPx(result, result.frames.back());
  std::cout << "swatbotics: " << registered << " of " << with_tags << " photos with tags registered, "
            << result.tags.size() << " tags mapped, reprojection RMS " << result.reprojection_rms_px
            << " px; loop: first photo " << first_rms << " px, last photo " << last_rms << " px\n";
  // Measured 2026-12-06: 72 of 72 registered, 19 of the 20 tags mapped
  // (tag 18's views from the two passes of the loop disagree: docs/recon.md),
  // 0.41 px RMS; first photo 0.46 px, last 0.32 px.
  EXPECT_GE(registered, 66);
  EXPECT_LT(result.reprojection_rms_px, 0.6);
  EXPECT_LT(first_rms, 1.0);
  EXPECT_LT(last_rms, 1.0);
  // The size constraint relaxed: every learned tag's corners free.
  std::vector<FrameState*> frames;
  std::vector<FrameState> copy = result.frames;
  for (auto& f : copy) frames.push_back(&f);
  const auto edges = RelaxedTagEdgeLengths(frames, result.tags, result.camera.fx, result.camera.fy, {});
  double sum = 0, sum2 = 0;
  int n = 0;
  for (const auto& [id, e] : edges) {
    for (double length : e) {
      sum += length;
      sum2 += length * length;
      ++n;
    }
  }
  ASSERT_GT(n, 0);
  const double mean = sum / n, spread = std::sqrt(std::max(0.0, sum2 / n - mean * mean));
  std::cout << "swatbotics relaxed: " << edges.size() << " tags, edge length mean " << 1e3 * mean << " mm, spread "
            << 1e3 * spread << " mm (printed size 127 mm)\n";
  // Relaxed, the edges stay near the printed size: the map is metric
  // without the constraint forcing it (scale from the anchor tag only).
  EXPECT_NEAR(mean, 0.127, 0.127 * 0.05);
  // The loop closes: the first and last photos (tags 11, 13, 18, 19) both
  // register against the one map.
  EXPECT_TRUE(result.frames.front().registered);
  EXPECT_TRUE(result.frames.back().registered);
}

TEST(ReplayRealDataSlow, VispTagPosesAgainstReference) {
  TAGSFM_REQUIRE_SHARED_DATA("visp-apriltag/AprilTag");
  TempDir scratch;
  const fs::path dir = SharedDataDir() / "visp-apriltag/AprilTag";
  const ReconstructionResult result = Reconstruct(MakeRecording(
      scratch.path(),
      "{width: 640, height: 480, fx: 615.1674805, fy: 615.1675415, cx: 312.1889954, cy: 243.4373779, distortion: []}",
      0.053, {dir / "AprilTag.png"}));
  ASSERT_TRUE(result.frames.front().registered) << result.frames.front().reason;
  const Rigid3d cam_from_world = result.frames.front().cam_from_world.ToRigid();
  // ground_truth_pose.txt: "36h11_id:_N" then "tx ty tz tux tuy tuz" (camera from tag).
  std::ifstream truth(dir / "ground_truth_pose.txt");
  std::string name;
  std::vector<double> centre_errors, normal_errors;
  while (truth >> name) {
    double t[3], u[3];
    truth >> t[0] >> t[1] >> t[2] >> u[0] >> u[1] >> u[2];
    const TagId id = std::stoi(name.substr(name.rfind('_') + 1));
    auto it = result.tags.find(id);
    if (it == result.tags.end()) continue;
    const TagCorners corners = it->second.CornersInWorld();
    const Eigen::Vector3d centre = cam_from_world * TagCenter(corners);
    centre_errors.push_back((centre - Eigen::Vector3d(t[0], t[1], t[2])).norm());
    // The tag planes' normals, whatever each library's axis conventions.
    const Eigen::Vector3d axis(u[0], u[1], u[2]);
    const Eigen::Matrix3d r = Eigen::AngleAxisd(axis.norm(), axis.normalized()).toRotationMatrix();
    const Eigen::Vector3d normal = cam_from_world.rotation * (corners[1] - corners[0]).cross(corners[3] - corners[0]).normalized();
    normal_errors.push_back(std::acos(std::min(1.0, std::abs(normal.dot(r.col(2))))) * 180 / M_PI);
  }
  ASSERT_GE(centre_errors.size(), 10u);
  std::sort(centre_errors.begin(), centre_errors.end());
  std::sort(normal_errors.begin(), normal_errors.end());
  std::cout << "visp AprilTag.png: " << centre_errors.size() << " tags; centre vs ViSP median "
            << 1e3 * centre_errors[centre_errors.size() / 2] << " mm, max " << 1e3 * centre_errors.back()
            << " mm; normal median " << normal_errors[normal_errors.size() / 2] << " deg, max " << normal_errors.back()
            << " deg; reprojection RMS " << result.reprojection_rms_px << " px\n";
  // One view of small tags at ~0.5 m: depth from a 0.053 m square is good to
  // a few mm, the tilt to a few degrees (ViSP's own estimate is no truth).
  EXPECT_LT(centre_errors[centre_errors.size() / 2], 0.01);
  EXPECT_LT(normal_errors[normal_errors.size() / 2], 10.0);
}

// The hybrid on the room's 72 photos (plain walls, doors and frames),
// through `tagsfm replay` as a user runs it: every photo searched for tags,
// the lens refined from the targets. COLMAP 3.8 on the same photos gives
// 2,670 points at 0.61 px mean reprojection (docs/features.md); tagsfm
// gave 1,013 before the fits along epipolar lines and the triangulations
// again from the poses adjusted with the points, 2,091 after, 3,676 (at
// 0.36 px RMS) since the fits' limit follows the lines' error (0.23 px here),
// 5,381 (0.42 px) since a refused fit is tried again from tilted planes,
// 5,560 (0.41 px) since the fits take their first steps on every other
// pixel and stop at a step under 0.02 px.
TEST(ReplayRealDataSlow, SwatboticsFeaturePoints) {
  TAGSFM_REQUIRE_SHARED_DATA("swatbotics-mapping/images/mapping_feb_2014");
  TempDir scratch;
  const fs::path rec = scratch.path() / "rec", out = scratch.path() / "out";
  fs::create_directories(rec);
  MakeRecording(rec, "{width: 816, height: 612, fx: 765.00, fy: 764.18, cx: 393.72, cy: 304.66, distortion: []}", 0.127,
                ImagesIn(SharedDataDir() / "swatbotics-mapping/images/mapping_feb_2014", ".JPG"));
  std::ofstream(scratch.path() / "config.yaml") << "pipeline:\n  recon:\n    refine_intrinsics: true\n";
  const std::string command = testing::TagsfmExe().string() + " replay " + rec.string() + " --out " + out.string() +
                              " --tag-search every_frame --config " + (scratch.path() / "config.yaml").string() +
                              " > " + (scratch.path() / "log.txt").string() + " 2>&1";
  const int status = std::system(command.c_str());
  const auto log = ReadFileToString(scratch.path() / "log.txt");
  ASSERT_EQ(status, 0) << (log ? *log : std::string("(no log)"));
  const auto text = ReadFileToString(out / "report.json");
  ASSERT_TRUE(text.has_value());
  const nlohmann::json report = nlohmann::json::parse(*text);
  const int points = report["feature_points"];
  const double rms = report["feature_reprojection_rms_px"];
  const double epipolar_sigma = report["feature_triangulation"]["epipolar_sigma_px"];
  std::cout << "swatbotics hybrid: " << points << " points at " << rms << " px RMS; epipolar lines' error "
            << epipolar_sigma << " px, " << report["feature_triangulation"]["line_fits"] << " line fits; cameras moved "
            << report["points_shift_px"] << " px at the points\n";
  EXPECT_EQ(report["registered_frames"], 72);
  // 20 % under the measured 5,560 (2,130 with the fits' fixed limit, 3,676
  // before the fits out of iterations, the second references and the first
  // pass at the fits' reach, 4,659 before the tilted starts;
  // docs/features.md).
  EXPECT_GE(points, 4448);
  EXPECT_LE(rms, 0.61);  // COLMAP's
  // The targets alone leave the poses ~1 px from the scene's: the points
  // are triangulated again from the adjusted poses.
  EXPECT_GE(report["points_refits"].get<int>(), 1);
  EXPECT_GT(epipolar_sigma, 0.0);
}

TEST(ReplayRealDataSlow, VideoSingleTagIsSmooth) {
  TAGSFM_REQUIRE_SHARED_DATA("video-single-tag/frames");
  TempDir scratch;
  const auto images = ImagesIn(SharedDataDir() / "video-single-tag/frames", ".jpg");
  ASSERT_EQ(images.size(), 93u);
  const ReconstructionResult result = Reconstruct(MakeRecording(
      scratch.path(), "{width: 640, height: 480, fx: 823.8, fy: 822.8, cx: 304.8, cy: 236.3, distortion: []}", 0.14,
      images));
  int registered = 0;
  std::vector<double> rotation_jumps, centre_jumps;
  const FrameState* previous = nullptr;
  for (const auto& f : result.frames) {
    if (!f.registered) continue;
    ++registered;
    if (previous) {
      rotation_jumps.push_back(
          RotationAngleDeg(previous->cam_from_world.ToRigid().rotation, f.cam_from_world.ToRigid().rotation));
      centre_jumps.push_back((previous->cam_from_world.ToRigid().Center() - f.cam_from_world.ToRigid().Center()).norm());
    }
    previous = &f;
  }
  ASSERT_GE(rotation_jumps.size(), 2u);
  std::sort(rotation_jumps.begin(), rotation_jumps.end());
  std::sort(centre_jumps.begin(), centre_jumps.end());
  std::cout << "video-single-tag: " << registered << " of 93 frames registered; frame-to-frame rotation median "
            << rotation_jumps[rotation_jumps.size() / 2] << " deg, max " << rotation_jumps.back()
            << " deg; centre median " << 1e3 * centre_jumps[centre_jumps.size() / 2] << " mm, max "
            << 1e3 * centre_jumps.back() << " mm; reprojection RMS " << result.reprojection_rms_px << " px\n";
  EXPECT_EQ(registered, 93);
  // A hand-held video at 30 fps turns a few degrees per frame at most: a
  // planar-ambiguity flip would show as a jump of tens of degrees.
  EXPECT_LT(rotation_jumps.back(), 10.0);
}

}  // namespace
}  // namespace tagsfm
