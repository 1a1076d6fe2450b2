// Tag corners of rendered recordings against their truth, as JSON: the true
// corners projected with the true poses and the recording's camera, the
// detections of every frame by the full-frame detector (or the tracker, as
// replay runs it), binned by module size and by view angle (between the
// tag's normal and the ray to its centre). "size_ppm" is the mean relative
// error of the detected tags' side lengths: what a self-survey's scale
// inherits when every tag looks that much larger (+) or smaller (-).
//
//   corner_truth_bench REC... [--tracking] [--no-camera]
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <iostream>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "tagsfm/capture/recording.h"
#include "tagsfm/core/csv_formats.h"
#include "tagsfm/detect/tag_detector.h"
#include "tagsfm/detect/tag_tracker.h"

namespace fs = std::filesystem;
using namespace tagsfm;

namespace {

struct Bin {
  std::vector<double> errors, outward;
  std::vector<double> side_ratio;  // detected / true side length - 1, per side
  std::vector<double> edge_outward;  // per edge: the detected corners' mean offset outside the true edge line
  std::vector<double> view_outward;  // per tag view: its four corners' mean outward offset
  void Add(const Bin& other) {
    view_outward.insert(view_outward.end(), other.view_outward.begin(), other.view_outward.end());
    edge_outward.insert(edge_outward.end(), other.edge_outward.begin(), other.edge_outward.end());
    errors.insert(errors.end(), other.errors.begin(), other.errors.end());
    outward.insert(outward.end(), other.outward.begin(), other.outward.end());
    side_ratio.insert(side_ratio.end(), other.side_ratio.begin(), other.side_ratio.end());
  }
};

double Percentile(std::vector<double> v, double q) {
  if (v.empty()) return NAN;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, static_cast<size_t>(q * (v.size() - 1) + 0.5))];
}

// Mean of the values within 0.5 (px) of zero.
double Mean(const std::vector<double>& values) {
  double sum = 0;
  int count = 0;
  for (double v : values) {
    if (std::abs(v) > 0.5) continue;
    sum += v;
    ++count;
  }
  return count ? sum / count : NAN;
}

// Standard deviation of the values within 0.5 (px) of zero.
double SpreadWithin(const std::vector<double>& values) {
  const double mean = Mean(values);
  double sum = 0;
  int count = 0;
  for (double v : values) {
    if (std::abs(v) > 0.5) continue;
    sum += (v - mean) * (v - mean);
    ++count;
  }
  return count > 1 ? std::sqrt(sum / (count - 1)) : NAN;
}

nlohmann::json BinJson(const Bin& bin) {
  // Inliers: corners within 0.5 px (an occluded tag or a declined fit
  // would otherwise dominate a mean of a thousandth of a pixel).
  double outward_sum = 0, ratio_sum = 0;
  int inliers = 0, ratio_inliers = 0;
  for (size_t i = 0; i < bin.errors.size(); ++i) {
    if (bin.errors[i] > 0.5) continue;
    outward_sum += bin.outward[i];
    ++inliers;
  }
  for (double r : bin.side_ratio) {
    if (std::abs(r) > 0.02) continue;
    ratio_sum += r;
    ++ratio_inliers;
  }
  return {{"corners", bin.errors.size()},
          {"median_px", Percentile(bin.errors, 0.5)},
          {"p95_px", Percentile(bin.errors, 0.95)},
          {"outward_bias_px", inliers ? outward_sum / inliers : NAN},
          {"size_ppm", ratio_inliers ? 1e6 * ratio_sum / ratio_inliers : NAN},
          // A view's size error: independent corners would spread its mean
          // outward offset by half a corner's; the edges they share spread it more.
          {"outward_sd_px", SpreadWithin(bin.outward)},
          {"view_outward_sd_px", SpreadWithin(bin.view_outward)},
          {"edges", bin.edge_outward.size()},
          {"edge_outward_px", Mean(bin.edge_outward)}};
}

// Module size bins (px, mean side / 10 modules for the 36h11 print's 8
// black modules plus a white one each side is not assumed: side / 8).
const std::vector<double> kBinEdges = {0, 2, 3, 4, 6, 1e9};

const std::vector<double> kAngleEdges = {0, 30, 45, 60, 75, 90};
const std::vector<double> kAcrossEdges = {0, 1.5, 2, 2.5, 3, 4, 1e9};

int BinOf(const std::vector<double>& edges, double value) {
  for (size_t b = 1; b < edges.size(); ++b)
    if (value < edges[b]) return static_cast<int>(b - 1);
  return static_cast<int>(edges.size() - 2);
}

// Degrees between the tag's normal and the ray from the camera to its centre.
double ViewAngleDeg(const std::array<Eigen::Vector3d, 4>& in_cam) {
  const Eigen::Vector3d normal = (in_cam[1] - in_cam[0]).cross(in_cam[3] - in_cam[0]).normalized();
  const Eigen::Vector3d ray = (0.25 * (in_cam[0] + in_cam[1] + in_cam[2] + in_cam[3])).normalized();
  return std::acos(std::min(1.0, std::abs(normal.dot(ray)))) * 180.0 / M_PI;
}

nlohmann::json BinsJson(const std::vector<Bin>& bins, const std::vector<double>& edges, const char* unit) {
  nlohmann::json out = nlohmann::json::object();
  for (size_t b = 0; b < bins.size(); ++b) {
    if (bins[b].errors.empty()) continue;
    char name[64];
    std::snprintf(name, sizeof(name), "%g_to_%g_%s", edges[b], std::min(edges[b + 1], 99.0), unit);
    out[name] = BinJson(bins[b]);
  }
  return out;
}

// A tag's true corners in the camera and in the image; none when a corner
// is behind (or at) the camera.
struct TrueTag {
  std::array<Eigen::Vector3d, 4> in_cam;
  QuadCorners px;
};
std::optional<TrueTag> ProjectTruth(const Rigid3d& cam_from_world, const std::array<Eigen::Vector3d, 4>& corners,
                                    const CameraModel& camera) {
  TrueTag t;
  for (int k = 0; k < 4; ++k) {
    t.in_cam[k] = cam_from_world * corners[k];
    if (!(t.in_cam[k].z() > 0.05)) return std::nullopt;
    t.px[k] = camera.Project(t.in_cam[k]);
  }
  return t;
}

// What the recording's detections add up to.
struct Tally {
  std::vector<Bin> by_module = std::vector<Bin>(kBinEdges.size() - 1);
  std::vector<Bin> by_angle = std::vector<Bin>(kAngleEdges.size() - 1);
  std::vector<Bin> by_across = std::vector<Bin>(kAcrossEdges.size() - 1);
  int found = 0, wrong = 0;
};

// One detected tag against its truth: each corner's error, its offset
// along the outward diagonal and its side's length error, binned by module
// size and view angle; each edge's offset outside its true line, binned by
// one module's width across it (the border's image width: what the blur
// meets).
void AddTag(const TagDetection& det, const TrueTag& truth, const CameraModel& camera, Tally* tally) {
  const QuadCorners& px = truth.px;
  const Eigen::Vector2d centre = 0.25 * (px[0] + px[1] + px[2] + px[3]);
  double side_sum = 0;
  Bin one;
  for (int k = 0; k < 4; ++k) {
    const Eigen::Vector2d offset = det.corners[k] - px[k];
    const double true_side = (px[(k + 1) % 4] - px[k]).norm();
    side_sum += true_side;
    one.errors.push_back(offset.norm());
    one.outward.push_back(offset.dot((px[k] - centre).normalized()));
    one.side_ratio.push_back((det.corners[(k + 1) % 4] - det.corners[k]).norm() / true_side - 1);
  }
  one.view_outward.push_back(0.25 * (one.outward[0] + one.outward[1] + one.outward[2] + one.outward[3]));
  tally->by_module[BinOf(kBinEdges, side_sum / 4 / 8)].Add(one);
  tally->by_angle[BinOf(kAngleEdges, ViewAngleDeg(truth.in_cam))].Add(one);
  const Eigen::Vector3d centre3 = 0.25 * (truth.in_cam[0] + truth.in_cam[1] + truth.in_cam[2] + truth.in_cam[3]);
  for (int k = 0; k < 4; ++k) {
    const Eigen::Vector2d a = px[k], b = px[(k + 1) % 4];
    Eigen::Vector2d normal(-(b - a).y(), (b - a).x());
    normal.normalize();
    if (normal.dot(a - centre) < 0) normal = -normal;
    const Eigen::Vector3d mid3 = 0.5 * (truth.in_cam[k] + truth.in_cam[(k + 1) % 4]);
    const Eigen::Vector2d inward_px = camera.Project(mid3 + 0.25 * (centre3 - mid3));
    const double across = normal.dot(camera.Project(mid3) - inward_px);
    Bin edge;
    edge.edge_outward.push_back(0.5 * (normal.dot(det.corners[k] - a) + normal.dot(det.corners[(k + 1) % 4] - b)));
    tally->by_across[BinOf(kAcrossEdges, across)].Add(edge);
  }
}

nlohmann::json TallyJson(const Tally& tally) {
  nlohmann::json out = {{"tags", tally.found}, {"wrong_ids", tally.wrong}};
  Bin all;
  for (const Bin& bin : tally.by_module) all.Add(bin);
  out["by_module"] = BinsJson(tally.by_module, kBinEdges, "px");
  out["by_view_angle"] = BinsJson(tally.by_angle, kAngleEdges, "deg");
  nlohmann::json across = nlohmann::json::object();
  for (size_t b = 0; b < tally.by_across.size(); ++b) {
    if (tally.by_across[b].edge_outward.empty()) continue;
    char name[64];
    std::snprintf(name, sizeof(name), "%g_to_%g_px", kAcrossEdges[b], std::min(kAcrossEdges[b + 1], 99.0));
    across[name] = {{"edges", tally.by_across[b].edge_outward.size()}, {"outward_px", Mean(tally.by_across[b].edge_outward)}};
  }
  out["edges_by_module_across"] = across;
  out["all"] = BinJson(all);
  return out;
}

nlohmann::json Measure(const fs::path& dir, bool tracking, bool with_camera) {
  auto reader = RecordingReader::Open(dir);
  if (!reader) return {{"error", reader.error().message}};
  auto targets = ReadTargetsCsv(dir / "ground_truth/targets.csv");
  auto poses = ReadPosesCsv(dir / "ground_truth/poses.csv");
  if (!targets || !poses || !reader->info().camera) return {{"error", "needs ground_truth/ and a camera"}};
  const CameraModel& camera = *reader->info().camera;
  TagDetectorOptions options;
  options.family = reader->info().targets.family;
  if (with_camera) options.camera = camera;
  auto detector = TagDetector::Create(options);
  auto tracker = TagTracker::Create(options, TagTrackerOptions{});
  if (!detector || !tracker) return {{"error", "detector"}};
  Tally tally;
  for (size_t i = 0; i < reader->entries().size(); ++i) {
    auto frame = reader->LoadFrame(i);
    if (!frame) return {{"error", frame.error().message}};
    const auto pose = poses->find(frame->index);
    if (pose == poses->end()) continue;
    auto detections = tracking ? (*tracker)->Track(frame->gray, frame->index) : (*detector)->Detect(frame->gray, frame->index);
    if (!detections) return {{"error", detections.error().message}};
    for (const TagDetection& det : detections->tags) {
      const auto truth = targets->find(det.id);
      if (truth == targets->end()) {
        ++tally.wrong;
        continue;
      }
      const std::optional<TrueTag> true_tag = ProjectTruth(pose->second, truth->second, camera);
      if (!true_tag) continue;
      ++tally.found;
      AddTag(det, *true_tag, camera, &tally);
    }
  }
  nlohmann::json out = TallyJson(tally);
  out["recording"] = dir.string();
  out["mode"] = tracking ? "tracking" : "full_frame";
  out["camera"] = with_camera;
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  bool tracking = false, with_camera = true;
  std::vector<fs::path> recordings;
  for (int i = 1; i < argc; ++i) {
    if (!std::strcmp(argv[i], "--tracking")) tracking = true;
    else if (!std::strcmp(argv[i], "--no-camera")) with_camera = false;
    else recordings.emplace_back(argv[i]);
  }
  if (recordings.empty()) {
    std::fprintf(stderr, "usage: corner_truth_bench REC... [--tracking] [--no-camera]\n");
    return 2;
  }
  nlohmann::json out = nlohmann::json::array();
  for (const fs::path& rec : recordings) out.push_back(Measure(rec, tracking, with_camera));
  std::cout << out.dump(1) << "\n";
  return 0;
}
