// The feature stage (feature/) on a recording with known poses, as JSON:
// features, matches, tracks, points, and, on rendered recordings, the
// points' distances to the true surfaces. docs/features.md's figures.
//
//   feature_map_bench synth REC [options]        poses and surfaces from REC/ground_truth
//   feature_map_bench poses REC OUT [options]    poses, targets and camera from a replay's OUT (real photos)
//   feature_map_bench middlebury DIR [options]   DIR/*_par.txt: exact cameras, no targets
//
// options: --max-features N --contrast C --relative-contrast 0|1 --plain-sift 0|1 --image-scale S --epipolar PX --ratio R --grid-cell PX
//          --max-distance D --neighbours N --min-overlap S --max-view-angle DEG --min-angle DEG
//          --max-view-error PX --max-rms PX --max-relative-sigma S --feature-sigma PX --min-views N
//          --refine 0|1 --keep-unrefined 0|1 --refined-sigma PX --half-window N --min-correlation C --max-fit-sigma PX --fit-sigma-per-epipolar K --max-shift PX --balance-scale 0|1 --max-level N
//          --depth-factor F --every N --threads N
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include <Eigen/Eigenvalues>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "tagsfm/capture/recording.h"
#include "tagsfm/core/csv_formats.h"
#include "tagsfm/detect/tag_detector.h"
#include "tagsfm/eval/scene_geometry.h"
#include "tagsfm/export/feature_triangulation_json.h"
#include "tagsfm/feature/feature_map.h"

namespace fs = std::filesystem;
using namespace tagsfm;

namespace {

double Ms(std::chrono::steady_clock::time_point since) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - since).count();
}

double Median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::nth_element(v.begin(), v.begin() + static_cast<long>(v.size() / 2), v.end());
  return v[v.size() / 2];
}

struct Input {
  CameraModel camera;
  struct Image {
    FrameId frame;
    cv::Mat gray, colour;
    Rigid3d cam_from_world;
    DetectionSet tags;  // detected (recordings) or none (Middlebury)
  };
  std::vector<Image> images;
  TargetCornerMap targets;  // for the depth range and the tag mask; empty: none
  std::vector<eval::SurfaceRectangle> surfaces;
  double fallback_depth = 0;  // without targets: distance to the cameras' common look-at point
};

// Depth range of a view: the median depth of the target corners in view
// (or the fallback) divided and multiplied by the factor.
DepthRange DepthOf(const Input& in, const Rigid3d& cam_from_world, double factor) {
  std::vector<double> depths;
  for (const auto& [id, corners] : in.targets) {
    for (const Eigen::Vector3d& c : corners) {
      const Eigen::Vector3d x = cam_from_world * c;
      if (x.z() <= 0) continue;
      const Eigen::Vector2d p = in.camera.Project(x);
      if (p.x() >= 0 && p.y() >= 0 && p.x() < in.camera.width && p.y() < in.camera.height) depths.push_back(x.z());
    }
  }
  const double d = depths.empty() ? in.fallback_depth : Median(depths);
  return DepthRange::Around(d, factor);
}

Input LoadRecording(const fs::path& rec, const PoseMap& poses, int every) {
  Input in;
  auto reader = RecordingReader::Open(rec);
  if (!reader) throw std::runtime_error(reader.error().message);
  in.camera = *reader->info().camera;
  TagDetectorOptions detector_options;
  detector_options.camera = in.camera;
  auto detector = TagDetector::Create(detector_options);
  if (!detector) throw std::runtime_error(detector.error().message);
  for (size_t i = 0; i < reader->entries().size(); i += static_cast<size_t>(every)) {
    auto frame = reader->LoadFrame(i);
    if (!frame) throw std::runtime_error(frame.error().message);
    const auto pose = poses.find(frame->index);
    if (pose == poses.end()) continue;
    auto tags = (*detector)->Detect(frame->gray, frame->index);
    if (!tags) throw std::runtime_error(tags.error().message);
    in.images.push_back({frame->index, frame->gray, frame->image.type() == CV_8UC3 ? frame->image : cv::Mat(), pose->second, *tags});
  }
  return in;
}

// Middlebury *_par.txt: name K(9) R(9) t(3), P = K [R | t].
Input LoadMiddlebury(const fs::path& dir) {
  Input in;
  fs::path par;
  for (const auto& e : fs::directory_iterator(dir)) {
    if (e.path().string().ends_with("_par.txt")) par = e.path();
  }
  std::ifstream file(par);
  int count = 0;
  file >> count;
  std::vector<Eigen::Vector3d> centres, axes;
  for (int i = 0; i < count; ++i) {
    std::string name;
    double k[9], r[9], t[3];
    file >> name;
    for (double& v : k) file >> v;
    for (double& v : r) file >> v;
    for (double& v : t) file >> v;
    Eigen::Matrix3d rm;
    rm << r[0], r[1], r[2], r[3], r[4], r[5], r[6], r[7], r[8];
    const cv::Mat image = cv::imread((dir / name).string(), cv::IMREAD_COLOR);
    if (i == 0) {
      in.camera.width = image.cols;
      in.camera.height = image.rows;
      in.camera.fx = k[0];
      in.camera.fy = k[4];
      in.camera.cx = k[2];
      in.camera.cy = k[5];
    }
    cv::Mat gray;
    cv::cvtColor(image, gray, cv::COLOR_BGR2GRAY);
    const Rigid3d pose(Eigen::Quaterniond(rm), Eigen::Vector3d(t[0], t[1], t[2]));
    in.images.push_back({i, gray, image, pose, DetectionSet{i, {}}});
    centres.push_back(pose.Center());
    axes.push_back(pose.rotation.conjugate() * Eigen::Vector3d::UnitZ());
  }
  // The point nearest every optical axis (least squares): what they look at.
  Eigen::Matrix3d a = Eigen::Matrix3d::Zero();
  Eigen::Vector3d b = Eigen::Vector3d::Zero();
  for (size_t i = 0; i < centres.size(); ++i) {
    const Eigen::Matrix3d p = Eigen::Matrix3d::Identity() - axes[i] * axes[i].transpose();
    a += p;
    b += p * centres[i];
  }
  const Eigen::Vector3d look_at = a.ldlt().solve(b);
  std::vector<double> d;
  for (const auto& c : centres) d.push_back((look_at - c).norm());
  in.fallback_depth = Median(d);
  return in;
}

struct BenchOptions {
  FeatureExtractorOptions extractor;
  FeatureMapOptions map;
  double depth_factor = 2.0;
  int every = 1;
  int threads = 1;  // for the matching, triangulation and refinement
};

// "--name value" pairs after the mode's arguments; false on an unknown name.
bool ParseOptions(int argc, char** argv, int first, BenchOptions& o) {
  for (int arg = first; arg + 1 < argc; arg += 2) {
    const std::string name = argv[arg];
    const double v = std::stod(argv[arg + 1]);
    TrackTriangulationOptions& t = o.map.triangulation;
    if (name == "--max-features") o.extractor.max_features = static_cast<int>(v);
    else if (name == "--contrast") o.extractor.contrast_threshold = v;
    else if (name == "--relative-contrast") o.extractor.contrast_relative_to_range = v != 0;
    else if (name == "--plain-sift") o.extractor.root_sift = v == 0;
    else if (name == "--image-scale") o.extractor.image_scale = v;
    else if (name == "--epipolar") o.map.matcher.epipolar_px = v;
    else if (name == "--ratio") o.map.matcher.ratio = v;
    else if (name == "--grid-cell") o.map.matcher.grid_cell_px = static_cast<int>(v);
    else if (name == "--max-distance") o.map.matcher.max_descriptor_distance = v;
    else if (name == "--neighbours") o.map.max_neighbours = static_cast<int>(v);
    else if (name == "--min-overlap") o.map.min_overlap = v;
    else if (name == "--max-view-angle") o.map.max_view_angle_deg = v;
    else if (name == "--min-angle") t.min_angle_deg = v;
    else if (name == "--max-view-error") t.max_view_error_px = v;
    else if (name == "--max-rms") t.max_reprojection_rms_px = v;
    else if (name == "--max-relative-sigma") t.max_relative_sigma = v;
    else if (name == "--feature-sigma") t.feature_sigma_px = v;
    else if (name == "--min-views") t.min_views = static_cast<int>(v);
    else if (name == "--refine") o.map.refine = v != 0;
    else if (name == "--keep-unrefined") o.map.keep_unrefined_views = v != 0;
    else if (name == "--refined-sigma") o.map.refined_feature_sigma_px = v;
    else if (name == "--half-window") o.map.refinement.half_window = static_cast<int>(v);
    else if (name == "--min-correlation") o.map.refinement.min_correlation = v;
    else if (name == "--max-fit-sigma") o.map.refinement.max_sigma_px = v;
    else if (name == "--fit-sigma-per-epipolar") o.map.max_fit_sigma_per_epipolar_sigma = v;
    else if (name == "--max-shift") o.map.refinement.max_shift_px = v;
    else if (name == "--reference-attempts") o.map.refinement.reference_attempts = static_cast<int>(v);
    else if (name == "--tilt-retries") o.map.refinement.tilt_retries = static_cast<int>(v);
    else if (name == "--tilt-step") o.map.refinement.tilt_step_deg = v;
    else if (name == "--converged-sigma-fraction") o.map.refinement.converged_sigma_fraction = v;
    else if (name == "--sparse-until") o.map.refinement.sparse_until_px = v;
    else if (name == "--max-level") o.map.refinement.max_level = static_cast<int>(v);
    else if (name == "--balance-scale") o.map.refinement.balance_scale = v != 0;
    else if (name == "--depth-factor") o.depth_factor = v;
    else if (name == "--every") o.every = static_cast<int>(v);
    else if (name == "--threads") o.threads = static_cast<int>(v);
    else {
      std::cerr << "unknown option " << name << "\n";
      return false;
    }
  }
  return true;
}

// The camera the replay in `out` ended with (report.json's "camera", which
// holds the refined lens when the replay refined it), or `given`: poses
// adjusted with one lens are consistent with that lens only.
CameraModel ReplayCamera(const fs::path& out, const CameraModel& given) {
  std::ifstream file(out / "report.json");
  if (!file) return given;
  const nlohmann::json c = nlohmann::json::parse(file).at("camera");
  CameraModel camera = given;
  camera.kind = c.at("model") == "fisheye" ? CameraModel::Kind::kFisheye : CameraModel::Kind::kPinhole;
  camera.width = c.at("width");
  camera.height = c.at("height");
  camera.fx = c.at("fx");
  camera.fy = c.at("fy");
  camera.cx = c.at("cx");
  camera.cy = c.at("cy");
  camera.distortion = c.at("distortion").get<std::vector<double>>();
  return camera;
}

// The recording or photo set of the mode; throws with a one-line message.
Input LoadInput(const std::string& mode, char** argv, int every) {
  Input in;
  if (mode == "synth") {
    const fs::path rec = argv[2];
    in = LoadRecording(rec, *ReadPosesCsv(rec / "ground_truth/poses.csv"), every);
    in.targets = *ReadTargetsCsv(rec / "ground_truth/targets.csv");
    in.surfaces = *eval::ReadSceneYaml(rec / "ground_truth/scene.yaml");
  } else if (mode == "poses") {
    in = LoadRecording(argv[2], *ReadPosesCsv(fs::path(argv[3]) / "poses.csv"), every);
    in.targets = *ReadTargetsCsv(fs::path(argv[3]) / "targets.csv");
    in.camera = ReplayCamera(argv[3], in.camera);
  } else if (mode == "middlebury") {
    in = LoadMiddlebury(argv[2]);
  } else {
    throw std::runtime_error("unknown mode " + mode);
  }
  return in;
}

// Extraction and matching of every image in turn, timed, into the map.
struct MapRun {
  PoseMap poses;
  double extract_ms = 0, add_ms = 0, triangulate_ms = 0;
  long long features = 0, matches = 0, pairs = 0;
  double image_mb = 0, descriptor_mb = 0;  // what the keyframes hold
  std::vector<FeatureTrack> tracks;
  std::vector<FeaturePoint> points;
  FeatureTriangulationStats triangulation;
};

Result<MapRun> RunMap(const Input& in, const BenchOptions& o) {
  auto map = FeatureMap::Create(in.camera, o.map);
  if (!map) return map.error();
  MapRun run;
  for (const auto& image : in.images) {
    auto t0 = std::chrono::steady_clock::now();
    auto f = ExtractFeatures(image.gray, image.colour, image.tags, o.extractor);
    run.extract_ms += Ms(t0);
    if (!f) return f.error();
    run.features += f->size();
    run.image_mb += static_cast<double>(f->image.total() * f->image.elemSize()) / 1e6;
    run.descriptor_mb += static_cast<double>(f->descriptors.total() * f->descriptors.elemSize()) / 1e6;
    t0 = std::chrono::steady_clock::now();
    auto stats = map->AddKeyframe(std::move(*f), image.cam_from_world, DepthOf(in, image.cam_from_world, o.depth_factor),
                                  o.threads);
    run.add_ms += Ms(t0);
    if (!stats) return stats.error();
    run.matches += stats->matches;
    run.pairs += static_cast<long long>(stats->matched_with.size());
    run.poses[image.frame] = image.cam_from_world;
  }
  const auto t0 = std::chrono::steady_clock::now();
  run.tracks = map->Tracks();
  run.points = map->Triangulate(run.poses, in.camera, o.threads, &run.triangulation);
  run.triangulate_ms = Ms(t0);
  return run;
}

// Counts, timings and the points' reprojection errors.
nlohmann::json Summary(const Input& in, const MapRun& run) {
  nlohmann::json out;
  const double keyframes = static_cast<double>(in.images.size());
  out["keyframes"] = in.images.size();
  out["features_per_keyframe"] = static_cast<double>(run.features) / keyframes;
  out["extract_ms_per_keyframe"] = run.extract_ms / keyframes;
  out["add_ms_per_keyframe"] = run.add_ms / keyframes;
  out["image_mb_per_keyframe"] = run.image_mb / keyframes;
  out["descriptor_mb_per_keyframe"] = run.descriptor_mb / keyframes;
  out["pairs"] = run.pairs;
  out["matches_per_pair"] = run.pairs ? static_cast<double>(run.matches) / static_cast<double>(run.pairs) : 0.0;
  out["match_ms_per_pair"] = run.pairs ? run.add_ms / static_cast<double>(run.pairs) : 0.0;
  out["tracks"] = run.tracks.size();
  std::map<size_t, int> tracks_by_length;
  for (const FeatureTrack& t : run.tracks) ++tracks_by_length[std::min<size_t>(t.observations.size(), 10)];
  for (const auto& [length, count] : tracks_by_length) out["tracks_by_views"][std::to_string(length)] = count;
  out["triangulate_ms"] = run.triangulate_ms;
  out["points"] = run.points.size();
  out["triangulation"] = FeatureTriangulationJson(run.triangulation);
  double sum_sq = 0, sum = 0;
  long long observations = 0;
  std::map<size_t, int> by_length;
  for (const FeaturePoint& p : run.points) {
    observations += static_cast<long long>(p.observations.size());
    ++by_length[std::min<size_t>(p.observations.size(), 10)];
    for (const auto& [frame, pixel] : p.observations) {
      const double e = (in.camera.Project(run.poses.at(frame) * p.position) - pixel).norm();
      sum += e;
      sum_sq += e * e;
    }
  }
  const double n = static_cast<double>(observations);
  out["mean_track_length"] = run.points.empty() ? 0.0 : n / static_cast<double>(run.points.size());
  out["mean_reprojection_px"] = observations ? sum / n : 0.0;
  out["rms_reprojection_px"] = observations ? std::sqrt(sum_sq / n) : 0.0;
  for (const auto& [length, count] : by_length) out["points_by_views"][std::to_string(length)] = count;
  return out;
}

// The points' distances to the true surfaces: shares within 0.5-5 mm, and
// against each point's predicted sigma.
void AddSurfaceScores(const Input& in, const std::vector<FeaturePoint>& points, nlohmann::json& out) {
  if (in.surfaces.empty() || points.empty()) return;
  std::vector<double> d;
  for (const FeaturePoint& p : points) d.push_back(eval::DistanceToSurfaces(in.surfaces, p.position));
  for (double mm : {0.5, 1.0, 2.0, 5.0}) {
    const auto n = std::count_if(d.begin(), d.end(), [&](double x) { return x <= mm * 1e-3; });
    out["within_mm"][std::to_string(mm).substr(0, 3)] = static_cast<double>(n) / static_cast<double>(d.size());
    out["points_within_mm"][std::to_string(mm).substr(0, 3)] = n;
  }
  out["median_mm"] = 1e3 * Median(d);
  // Distance over the covariance's largest axis: beyond 3, a wrong match
  // (or a noise model too optimistic), not noise.
  int beyond3 = 0;
  std::map<int, std::pair<int, int>> by_sigma;  // predicted sigma (mm, rounded up) -> points, within 2 mm
  for (size_t i = 0; i < points.size(); ++i) {
    const double s = std::sqrt(Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(points[i].covariance).eigenvalues()(2));
    beyond3 += d[i] > 3 * s;
    auto& b = by_sigma[std::min(10, static_cast<int>(std::ceil(s * 1e3)))];
    ++b.first;
    b.second += d[i] <= 2e-3;
  }
  out["share_beyond_3_sigma"] = static_cast<double>(beyond3) / static_cast<double>(points.size());
  for (const auto& [mm, b] : by_sigma) out["within_2mm_by_sigma_mm"][std::to_string(mm)] = {b.first, static_cast<double>(b.second) / b.first};
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 3) {
    std::cerr << "usage: feature_map_bench synth REC | poses REC OUT | middlebury DIR [options]\n";
    return 2;
  }
  const std::string mode = argv[1];
  BenchOptions options;
  if (!ParseOptions(argc, argv, mode == "poses" ? 4 : 3, options)) return 2;
  Input in;
  try {
    in = LoadInput(mode, argv, options.every);
  } catch (const std::exception& e) {
    std::cerr << e.what() << "\n";
    return 1;
  }
  const Result<MapRun> run = RunMap(in, options);
  if (!run) {
    std::cerr << run.error().message << "\n";
    return 1;
  }
  nlohmann::json out = Summary(in, *run);
  AddSurfaceScores(in, run->points, out);
  std::cout << out.dump() << "\n";
  return 0;
}
