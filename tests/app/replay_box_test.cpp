// tagsfm replay end to end on the bundled synthetic box recording, against
// its ground truth; and the contract's behaviour on bad input.
#include <sys/wait.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <sstream>

#include <Eigen/Eigenvalues>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "json_file.h"
#include "tagsfm/core/csv_formats.h"
#include "tagsfm/core/file_util.h"
#include "tagsfm/eval/scene_geometry.h"
#include "tagsfm/eval/truth_comparison.h"
#include "tagsfm/export/feature_points_csv.h"
#include "run_command.h"
#include "test_paths.h"

namespace tagsfm {
namespace {

namespace fs = std::filesystem;
using testing::RecordingsDir;
using testing::TagsfmExe;
using testing::TempDir;
using testing::ReadJsonFile;
using testing::ReadText;

struct CommandRun {
  int exit_code = -1;
  std::string err;
};

CommandRun Tagsfm(const std::string& args, const fs::path& scratch) {
  const fs::path err = scratch / "stderr.txt";
  const std::string command =
      TagsfmExe().string() + " " + args + " 2> " + err.string() + " > " + (scratch / "stdout.txt").string();
  CommandRun run;
  const int status = std::system(command.c_str());
  run.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  // Messages may go to either stream (spdlog's default sink is stdout).
  auto text = ReadFileToString(err);
  if (text) run.err = *text;
  auto out = ReadFileToString(scratch / "stdout.txt");
  if (out) run.err += *out;
  return run;
}

fs::path Box() { return RecordingsDir() / "box_small"; }

void ExpectContractFiles(const fs::path& out) {
  for (const char* name : {"poses.csv", "targets.csv", "report.json", "cloud.ply", "colmap/cameras.txt",
                           "colmap/images.txt", "colmap/points3D.txt", "preview.png"}) {
    EXPECT_TRUE(fs::exists(out / name)) << name;
  }
  const nlohmann::json report = ReadJsonFile(out / "report.json");
  for (const char* key : {"frames", "registered_frames", "frames_skipped", "targets_seen", "points",
                          "reprojection_rms_px", "target_reprojection_rms_px", "runtime_s", "frame_latency_ms",
                          "peak_rss_mb", "pose_methods", "unregistered_frames"}) {
    EXPECT_TRUE(report.contains(key)) << key;
  }
  // cloud.ply: the header the evaluator reads, and as many vertices as points.
  std::ifstream ply(out / "cloud.ply", std::ios::binary);
  std::string line, header;
  while (std::getline(ply, line) && line != "end_header") header += line + "\n";
  EXPECT_NE(header.find("format binary_little_endian 1.0"), std::string::npos);
  EXPECT_NE(header.find("element vertex " + std::to_string(report["points"].get<int>())), std::string::npos);
  EXPECT_NE(header.find("property double x\nproperty double y\nproperty double z\nproperty uchar red\nproperty uchar "
                        "green\nproperty uchar blue\nproperty int track_length\nproperty float reprojection_error"),
            std::string::npos);
  const auto data_start = ply.tellg();
  ply.seekg(0, std::ios::end);
  EXPECT_EQ(static_cast<long>(ply.tellg() - data_start), report["points"].get<long>() * (3 * 8 + 3 + 4 + 4));
}

TEST(ReplayBoxSlow, KnownMapPosesMatchTheTruth) {
  TempDir scratch;
  const fs::path out = scratch.path() / "out";
  const CommandRun run = Tagsfm("replay " + Box().string() + " --out " + out.string() + " --targets " +
                             (Box() / "ground_truth/targets.csv").string(),
                         scratch.path());
  ASSERT_EQ(run.exit_code, 0) << run.err;
  ExpectContractFiles(out);
  const eval::TruthComparison c = eval::CompareWithTruth(*ReadPosesCsv(out / "poses.csv"), *ReadTargetsCsv(out / "targets.csv"),
                                             *ReadPosesCsv(Box() / "ground_truth/poses.csv"),
                                             *ReadTargetsCsv(Box() / "ground_truth/targets.csv"), false);
  // Every frame registers. Measured (2026-11-22): rotation median 0.015 deg,
  // max 0.20 deg (a frame seeing few tags of one face), centre median
  // 0.38 mm. Bounds at about twice that: a regression check, not the
  // issue's goal (0.006 deg / 0.2 mm), which this 640x480 capture misses.
  EXPECT_EQ(c.frames_compared, c.frames_in_truth);
  EXPECT_LT(c.rotation_median_deg, 0.03);
  EXPECT_LT(c.rotation_max_deg, 0.4);
  EXPECT_LT(c.centre_median_m, 0.001);
  const nlohmann::json report = ReadJsonFile(out / "report.json");
  EXPECT_LT(report["target_reprojection_rms_px"].get<double>(), 0.3);  // the bound
  // The known map fixes the scale: the images add no sigma of their own.
  EXPECT_TRUE(report["scale"]["images_sigma_rel"].is_null()) << report["scale"].dump();
}

// Feature points (SIFT tracks triangulated from the target-derived poses)
// against the true surfaces of the scene. The camera sees the box from about
// 2 m with f = 500 px; the features reproject at ~0.28 px RMS, i.e. ~1.1 mm
// across the ray at 2 m, and the depth error is that divided by the sine of
// the track's angle (3 to ~15 degrees over a 50-degree arc): measured
// (2026-11-22) 4,296 points, median 2.2 mm, p95 21 mm off the true surfaces.
// Bounds at about twice that. A wrong scale, pose convention or pixel offset
// (OpenCV's SIFT keypoints are +0.25 px off, corrected) moves points by
// centimetres.
TEST(ReplayBoxSlow, FeaturePointsLieOnTheTrueSurfaces) {
  TempDir scratch;
  const fs::path out = scratch.path() / "out";
  const CommandRun run = Tagsfm("replay " + Box().string() + " --out " + out.string() + " --targets " +
                                    (Box() / "ground_truth/targets.csv").string(),
                                scratch.path());
  ASSERT_EQ(run.exit_code, 0) << run.err;
  ExpectContractFiles(out);
  const nlohmann::json report = ReadJsonFile(out / "report.json");
  EXPECT_GE(report["feature_points"].get<int>(), 2000);
  EXPECT_EQ(report["points"].get<int>(), report["feature_points"].get<int>() + 4 * report["targets_mapped"].get<int>());
  EXPECT_LT(report["feature_reprojection_rms_px"].get<double>(), 0.5);
  // Where the tracks went adds up: every track of a pass is a point or has
  // one reason, the final pass takes the first's points the refinement kept,
  // and the adjustment keeps at most the final pass's points.
  const nlohmann::json& t = report["feature_triangulation"];
  for (const char* pass : {"first_pass", "final_pass"}) {
    const nlohmann::json& c = t[pass];
    EXPECT_EQ(c["tracks"].get<int>(), c["points"].get<int>() + c["too_few_views"].get<int>() + c["no_linear_point"].get<int>() +
                                          c["reprojection"].get<int>() + c["narrow_angle"].get<int>() +
                                          c["predicted_sigma"].get<int>())
        << pass;
  }
  EXPECT_EQ(t["final_pass"]["tracks"].get<int>(), t["first_pass"]["points"].get<int>() - t["refinement_dropped"].get<int>());
  // The box's faces seen obliquely: some views fit only from a tilted
  // plane's start (192 more points on box_small, docs/features.md).
  EXPECT_GE(t["tilted_fits"].get<int>(), 1);
  EXPECT_LE(report["feature_points"].get<int>(), t["final_pass"]["points"].get<int>());
  EXPECT_GE(report["feature_points"].get<int>(), t["final_pass"]["points"].get<int>() * 9 / 10);
  const CommandRun evaluate = Tagsfm("evaluate " + out.string() + " " + Box().string(), scratch.path());
  ASSERT_EQ(evaluate.exit_code, 0) << evaluate.err;
  const nlohmann::json e = ReadJsonFile(scratch.path() / "stdout.txt");
  const nlohmann::json& d = e["as_is"]["cloud_distance_m"];  // the known map puts it in the truth's frame
  EXPECT_EQ(d["count"].get<int>(), report["points"].get<int>());
  EXPECT_LT(d["median"].get<double>(), 0.004) << d.dump();
  EXPECT_LT(d["p95"].get<double>(), 0.04) << d.dump();

  // Each point's covariance explains its distance to the true surface: with
  // the largest axis of its error ellipsoid (an upper bound of the sigma
  // across the surface) at least 90 % lie within 3 sigma (measured 94 %
  // within 3 sigma along the surface normal; 99.7 % for a perfect Gaussian
  // model: the poses' own uncertainty and a few wrong matches are not in it).
  auto points = ReadFeaturePointsCsv(out / "features.csv");
  ASSERT_TRUE(points) << points.error().message;
  auto surfaces = eval::ReadSceneYaml(Box() / "ground_truth/scene.yaml");
  ASSERT_TRUE(surfaces) << surfaces.error().message;
  ASSERT_EQ(static_cast<int>(points->size()), report["feature_points"].get<int>());
  int within = 0;
  for (const auto& [id, p] : *points) {
    const double sigma_max = std::sqrt(Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(p.covariance).eigenvalues().maxCoeff());
    within += eval::DistanceToSurfaces(*surfaces, p.position) <= 3 * sigma_max;
  }
  EXPECT_GE(within, 0.9 * static_cast<double>(points->size())) << within << " of " << points->size();

  // measure: a feature point to another and to a target, with a sigma.
  const auto first = points->begin(), second = std::next(first);
  const CommandRun m = Tagsfm("measure " + out.string() + " p" + std::to_string(first->first) + " p" +
                                  std::to_string(second->first) + " --json",
                              scratch.path());
  ASSERT_EQ(m.exit_code, 0) << m.err;
  const nlohmann::json mj = ReadJsonFile(scratch.path() / "stdout.txt");
  EXPECT_NEAR(mj["distance_m"].get<double>(), (first->second.position - second->second.position).norm(), 1e-12);
  EXPECT_GT(mj["sigma_m"].get<double>(), 0.0);
  // Its sigma: the two points' covariances along the line, and the print
  // tolerance's share (report.json's scale.sigma_rel times the length), the
  // scale being what the rays cannot see.
  const Eigen::Vector3d u = (first->second.position - second->second.position).normalized();
  const double along = u.dot((first->second.covariance + second->second.covariance) * u);
  const double scale_part = report["scale"]["sigma_rel"].get<double>() * mj["distance_m"].get<double>();
  EXPECT_GT(scale_part, 0.0);
  EXPECT_NEAR(std::pow(mj["sigma_m"].get<double>(), 2), along + scale_part * scale_part, 1e-6 * (along + scale_part * scale_part));
  const CommandRun bad = Tagsfm("measure " + out.string() + " p1 p2", scratch.path());
  EXPECT_NE(bad.exit_code, 0);
  EXPECT_NE(bad.err.find("no feature point 1"), std::string::npos) << bad.err;

  // --no-features: targets alone.
  const fs::path targets_only = scratch.path() / "targets_only";
  ASSERT_EQ(Tagsfm("replay " + Box().string() + " --out " + targets_only.string() + " --no-features", scratch.path()).exit_code, 0);
  const nlohmann::json r = ReadJsonFile(targets_only / "report.json");
  EXPECT_EQ(r["feature_points"].get<int>(), 0);
  EXPECT_EQ(r["points"].get<int>(), 4 * r["targets_mapped"].get<int>());
}

// The adjustment with the points takes a sample of tie points (recon.
// tie_points_per_keyframe) and refines the others on the poses it adjusts:
// the same cloud as from every point. Without a map (the points move the
// poses most): measured 2026-12-05, 9,510 of 13,609 points as tie points,
// the points 7.4 um apart (median; 86 um at the 99th percentile), 95.7 %
// within 2 mm after a rigid fit either way (86.9 and 86.8 % within 1 mm).
// Bounds: the median 3x what was measured, a point at the 99th percentile
// 0.3 mm (a sixth of the 2 mm band), the shares within 0.5 points.
TEST(ReplayBoxSlow, TiePointsGiveTheCloudOfEveryPoint) {
  TempDir scratch;
  const fs::path all_config = scratch.path() / "all.yaml";
  {
    std::ofstream yaml(all_config);
    yaml << "pipeline:\n  recon:\n    tie_points_per_keyframe: 0\n";
  }
  struct Cloud {
    nlohmann::json report, rigid;
    std::map<long long, StoredFeaturePoint> points;
  };
  auto replay = [&](const std::string& name, const std::string& config) {
    Cloud c;
    const fs::path out = scratch.path() / name;
    const CommandRun run = Tagsfm("replay " + Box().string() + " --out " + out.string() + config, scratch.path());
    EXPECT_EQ(run.exit_code, 0) << run.err;
    c.report = ReadJsonFile(out / "report.json");
    EXPECT_EQ(Tagsfm("evaluate " + out.string() + " " + Box().string(), scratch.path()).exit_code, 0);
    c.rigid = ReadJsonFile(scratch.path() / "stdout.txt")["rigid"]["feature_points"];
    auto points = ReadFeaturePointsCsv(out / "features.csv");
    EXPECT_TRUE(points.has_value());
    if (points) c.points = std::move(*points);
    return c;
  };
  const Cloud tie = replay("tie", ""), all = replay("all", " --config " + all_config.string());
  ASSERT_FALSE(all.points.empty());
  ASSERT_EQ(tie.points.size(), all.points.size());
  EXPECT_EQ(all.report["points_adjusted"].get<int>(), all.report["feature_points"].get<int>());
  EXPECT_LT(tie.report["points_adjusted"].get<int>(), tie.report["feature_points"].get<int>());
  std::vector<double> apart;
  for (const auto& [id, p] : all.points) {
    auto it = tie.points.find(id);
    ASSERT_NE(it, tie.points.end()) << "point " << id;
    apart.push_back((it->second.position - p.position).norm());
  }
  std::sort(apart.begin(), apart.end());
  std::printf("tie points: %d of %d; apart median %.1f um, p99 %.1f um; within 2 mm %.4f / %.4f\n",
              tie.report["points_adjusted"].get<int>(), tie.report["feature_points"].get<int>(),
              1e6 * apart[apart.size() / 2], 1e6 * apart[apart.size() * 99 / 100], tie.rigid["within_2mm"].get<double>(),
              all.rigid["within_2mm"].get<double>());
  EXPECT_LT(apart[apart.size() / 2], 25e-6);
  EXPECT_LT(apart[apart.size() * 99 / 100], 3e-4);
  for (const char* share : {"within_1mm", "within_2mm", "within_5mm"}) {
    EXPECT_NEAR(tie.rigid[share].get<double>(), all.rigid[share].get<double>(), 0.005) << share;
  }
}

TEST(ReplayBoxSlow, WithoutMapTargetsAreMetricAndMatchTheTruth) {
  TempDir scratch;
  const fs::path out = scratch.path() / "out";
  const CommandRun run = Tagsfm("replay " + Box().string() + " --out " + out.string(), scratch.path());
  ASSERT_EQ(run.exit_code, 0) << run.err;
  ExpectContractFiles(out);
  const eval::TruthComparison c = eval::CompareWithTruth(*ReadPosesCsv(out / "poses.csv"), *ReadTargetsCsv(out / "targets.csv"),
                                             *ReadPosesCsv(Box() / "ground_truth/poses.csv"),
                                             *ReadTargetsCsv(Box() / "ground_truth/targets.csv"), true);
  // Measured (2026-11-22): 15 targets mapped (the others seen in too few of
  // the 20 frames of a 50-degree arc), corner RMS 1.10 mm = 1/2,300 of the
  // scene, scale +0.13 % (the corners' outward bias, ~0.07 px, makes tags
  // look nearer), 0.10 px reprojection RMS. Short of the 1/10,000
  // and 0.1 %; these bounds catch regressions.
  EXPECT_EQ(c.frames_compared, c.frames_in_truth);
  EXPECT_GE(c.targets_compared, 12);
  EXPECT_LT(c.corner_rms_m, c.scene_size_m / 1500);
  EXPECT_NEAR(c.scale, 1.0, 0.003);
  const nlohmann::json report = ReadJsonFile(out / "report.json");
  EXPECT_LT(report["target_reprojection_rms_px"].get<double>(), 0.3);
  EXPECT_TRUE(fs::exists(out / "targets_cov.csv"));
  // measure: a tag's diagonal is exact by construction (square of known size).
  const std::string anchor = std::to_string(report["anchor_tag"].get<int>());
  const CommandRun measure = Tagsfm("measure " + out.string() + " " + anchor + ":0 " + anchor + ":2 --json", scratch.path());
  ASSERT_EQ(measure.exit_code, 0) << measure.err;
  const nlohmann::json m = ReadJsonFile(scratch.path() / "stdout.txt");
  EXPECT_NEAR(m["distance_m"].get<double>(), 0.06 * std::sqrt(2.0), 1e-9);

  // The per-target table adds up to the run's totals, and its centre sigma
  // is the covariance's translation block with the scale's part: the
  // anchor's distance to the best-seen other tag, as `measure` gives it, has
  // a variance no larger than that tag's sigma_mm squared summed
  // (u^T S u <= trace S), and no smaller than the scale's part alone.
  const nlohmann::json& targets = report["targets"];
  ASSERT_EQ(targets.size(), report["targets_mapped"].get<size_t>());
  int views = 0, outliers = 0;
  const nlohmann::json* best = nullptr;
  for (const nlohmann::json& t : targets) {
    views += t["views"].get<int>();
    outliers += t["outlier_views"].get<int>();
    EXPECT_LT(t["rms_px"].get<double>(), 1.0) << t.dump();
    if (t["tag"].get<int>() == report["anchor_tag"].get<int>()) {
      EXPECT_TRUE(t["anchor"].get<bool>());
      EXPECT_TRUE(t["sigma_mm"].is_null()) << "the anchor is held fixed";
      continue;
    }
    ASSERT_EQ(t["sigma_mm"].size(), 3u) << t.dump();
    if (!best || t["views"].get<int>() > (*best)["views"].get<int>()) best = &t;
  }
  EXPECT_EQ(4 * views, report["observations"].get<int>());
  EXPECT_EQ(outliers, report["outlier_observations"].get<int>());
  ASSERT_NE(best, nullptr);
  const CommandRun pair =
      Tagsfm("measure " + out.string() + " " + anchor + " " + (*best)["tag"].dump() + " --json", scratch.path());
  ASSERT_EQ(pair.exit_code, 0) << pair.err;
  const nlohmann::json d = ReadJsonFile(scratch.path() / "stdout.txt");
  const double scale_part = report["scale"]["sigma_rel"].get<double>() * d["distance_m"].get<double>();
  const double variance = std::pow(d["sigma_m"].get<double>(), 2);
  double trace = 0;
  for (const nlohmann::json& s : (*best)["sigma_mm"]) trace += std::pow(1e-3 * s.get<double>(), 2);
  EXPECT_GT(variance, scale_part * scale_part * (1 + 1e-6));
  EXPECT_LE(variance, trace * (1 + 1e-6)) << (*best).dump();
  // The scale's sigma: the images' part and the print tolerance together.
  const double images = report["scale"]["images_sigma_rel"].get<double>();
  EXPECT_GT(images, 0);
  EXPECT_NEAR(report["scale"]["total_sigma_rel"].get<double>(),
              std::hypot(images, report["scale"]["sigma_rel"].get<double>()), 1e-12);
}

TEST(ReplayBoxSlow, UnreadableFrameIsSkippedAndCounted) {
  TempDir scratch;
  const fs::path rec = scratch.path() / "rec";
  fs::copy(Box(), rec, fs::copy_options::recursive);
  // Cut frame 5's image in half.
  auto index = ReadFileToString(rec / "frames.csv");
  ASSERT_TRUE(index.has_value());
  std::istringstream lines(*index);
  std::string line, file;
  for (int i = 0; std::getline(lines, line); ++i) {
    if (i == 6) file = SplitCsvLine(line)[2];
  }
  const fs::path image = fs::path(file).is_absolute() ? fs::path(file) : rec / file;
  fs::resize_file(image, fs::file_size(image) / 2);
  const fs::path out = scratch.path() / "out";
  const CommandRun run = Tagsfm("replay " + rec.string() + " --out " + out.string(), scratch.path());
  ASSERT_EQ(run.exit_code, 0) << run.err;
  EXPECT_NE(run.err.find("skipping frame 5"), std::string::npos) << run.err;
  const nlohmann::json report = ReadJsonFile(out / "report.json");
  EXPECT_EQ(report["frames_skipped"].get<int>(), 1);
  EXPECT_EQ(report["frames"].get<int>(), 20);
  EXPECT_EQ(report["registered_frames"].get<int>(), 19);
}

TEST(ReplayCommand, MissingRecordingIsAOneLineErrorNamingIt) {
  TempDir scratch;
  const CommandRun run =
      Tagsfm("replay " + (scratch.path() / "nothing").string() + " --out " + (scratch.path() / "out").string(),
             scratch.path());
  EXPECT_NE(run.exit_code, 0);
  EXPECT_NE(run.err.find("nothing"), std::string::npos) << run.err;
  EXPECT_EQ(std::count(run.err.begin(), run.err.end(), '\n'), 1) << run.err;  // one line
}

// box_small's 20 views are far apart (an orbit at 18 degrees a view): the
// tracker's predictions mostly fail and it backs off to full frames, so both
// modes see nearly the same tags and give nearly the same poses; report.json
// says which ran.
TEST(ReplayCommand, TagSearchModesAgreeOnSparseViewsAndABadModeIsNamed) {
  TempDir scratch;
  std::map<std::string, PoseMap> poses;
  for (const std::string mode : {"tracking", "every_frame"}) {
    const fs::path out = scratch.path() / mode;
    const CommandRun run = Tagsfm("replay " + Box().string() + " --no-features --tag-search " + mode + " --out " + out.string(),
                                  scratch.path());
    ASSERT_EQ(run.exit_code, 0) << run.err;
    const auto report = ReadJsonFile(out / "report.json");
    EXPECT_EQ(report["tag_search"]["mode"], mode);
    auto read = ReadPosesCsv(out / "poses.csv");
    ASSERT_TRUE(read.has_value());
    poses[mode] = *read;
  }
  ASSERT_EQ(poses["tracking"].size(), poses["every_frame"].size());
  for (const auto& [frame, pose] : poses["every_frame"]) {
    ASSERT_TRUE(poses["tracking"].count(frame)) << "frame " << frame;
    // Not to round-off: a tag found in a region starts the edge fit from
    // other libapriltag corners than the full frame's (the fit stops within
    // 1e-4 px of its minimum), and every_frame also looks for a tracked tag
    // the full frame missed in its region (one more tag view of 160 here).
    // Measured 3-140 um apart, against a median 1.4 mm from the truth.
    EXPECT_LT((poses["tracking"].at(frame).Center() - pose.Center()).norm(), 5e-4) << "frame " << frame;
  }
  const CommandRun bad = Tagsfm("replay " + Box().string() + " --tag-search often --out " +
                                (scratch.path() / "bad").string(), scratch.path());
  EXPECT_NE(bad.exit_code, 0);
  EXPECT_NE(bad.err.find("--tag-search"), std::string::npos) << bad.err;
}

TEST(ReplayMeasureCommand, UnknownTagIsAnErrorNamingIt) {
  TempDir scratch;
  const fs::path out = scratch.path() / "out";
  fs::create_directories(out);
  TargetCornerMap targets;
  targets[1] = {Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(1, 0, 0), Eigen::Vector3d(1, 1, 0), Eigen::Vector3d(0, 1, 0)};
  ASSERT_TRUE(WriteTargetsCsv(out / "targets.csv", targets).ok());
  const CommandRun run = Tagsfm("measure " + out.string() + " 1 99", scratch.path());
  EXPECT_NE(run.exit_code, 0);
  EXPECT_NE(run.err.find("tag 99"), std::string::npos) << run.err;
}

}  // namespace
}  // namespace tagsfm
