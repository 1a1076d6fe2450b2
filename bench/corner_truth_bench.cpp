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
  void Add(const Bin& other) {
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
  std::vector<Bin> bins(kBinEdges.size() - 1), by_angle(kAngleEdges.size() - 1), by_across(kAcrossEdges.size() - 1);
  int missing = 0, wrong = 0, found = 0;
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
        ++wrong;
        continue;
      }
      QuadCorners true_px;
      std::array<Eigen::Vector3d, 4> in_cam;
      bool in_front = true;
      for (int k = 0; k < 4; ++k) {
        in_cam[k] = pose->second * truth->second[k];
        in_front = in_front && in_cam[k].z() > 0.05;
        true_px[k] = in_front ? camera.Project(in_cam[k]) : Eigen::Vector2d::Zero();
      }
      if (!in_front) {
        ++missing;
        continue;
      }
      ++found;
      double side_sum = 0;
      for (int k = 0; k < 4; ++k) side_sum += (true_px[(k + 1) % 4] - true_px[k]).norm();
      Bin one;
      const Eigen::Vector2d centre = 0.25 * (true_px[0] + true_px[1] + true_px[2] + true_px[3]);
      for (int k = 0; k < 4; ++k) {
        const Eigen::Vector2d offset = det.corners[k] - true_px[k];
        one.errors.push_back(offset.norm());
        one.outward.push_back(offset.dot((true_px[k] - centre).normalized()));
        const double true_side = (true_px[(k + 1) % 4] - true_px[k]).norm();
        one.side_ratio.push_back((det.corners[(k + 1) % 4] - det.corners[k]).norm() / true_side - 1);
      }
      // Each edge: its offset outside the true line, binned by one module's
      // width across it (the border's image width: what the blur meets).
      const Eigen::Vector3d centre3 = 0.25 * (in_cam[0] + in_cam[1] + in_cam[2] + in_cam[3]);
      for (int k = 0; k < 4; ++k) {
        const Eigen::Vector2d a = true_px[k], b = true_px[(k + 1) % 4];
        Eigen::Vector2d normal(-(b - a).y(), (b - a).x());
        normal.normalize();
        if (normal.dot(a - centre) < 0) normal = -normal;
        const Eigen::Vector3d mid3 = 0.5 * (in_cam[k] + in_cam[(k + 1) % 4]);
        const Eigen::Vector2d inward_px = camera.Project(mid3 + 0.25 * (centre3 - mid3));
        const double across = normal.dot(camera.Project(mid3) - inward_px);
        Bin edge;
        edge.edge_outward.push_back(0.5 * (normal.dot(det.corners[k] - a) + normal.dot(det.corners[(k + 1) % 4] - b)));
        by_across[BinOf(kAcrossEdges, across)].Add(edge);
      }
      bins[BinOf(kBinEdges, side_sum / 4 / 8)].Add(one);
      by_angle[BinOf(kAngleEdges, ViewAngleDeg(in_cam))].Add(one);
    }
  }
  nlohmann::json out = {{"recording", dir.string()}, {"mode", tracking ? "tracking" : "full_frame"},
                        {"camera", with_camera}, {"tags", found}, {"wrong_ids", wrong}};
  Bin all;
  for (const Bin& bin : bins) all.Add(bin);
  out["by_module"] = BinsJson(bins, kBinEdges, "px");
  out["by_view_angle"] = BinsJson(by_angle, kAngleEdges, "deg");
  nlohmann::json across = nlohmann::json::object();
  for (size_t b = 0; b < by_across.size(); ++b) {
    if (by_across[b].edge_outward.empty()) continue;
    char name[64];
    std::snprintf(name, sizeof(name), "%g_to_%g_px", kAcrossEdges[b], std::min(kAcrossEdges[b + 1], 99.0));
    across[name] = {{"edges", by_across[b].edge_outward.size()}, {"outward_px", Mean(by_across[b].edge_outward)}};
  }
  out["edges_by_module_across"] = across;
  out["all"] = BinJson(all);
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
