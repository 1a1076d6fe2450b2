// Per-frame reconstruction latency (detection aside) on a 1000-frame
// synthetic video of tag correspondences: a box with tags on its faces,
// about 30 in view, 1280x720, 0.1 px corner noise; its last 200 frames go
// over the first 200 frames' views again. Prints JSON: p50/p95/max per mode,
// and p95 of frames 100-200 against 900-1000, which see the same views (the
// per-frame cost must not grow with the sequence).
//   build/bench/recon_latency_bench [frames [known_map|no_map]]   (default: 1000, both)

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <thread>

#include <nlohmann/json.hpp>

#include "tagsfm/core/cpu_time.h"
#include "tagsfm/core/peak_rss.h"
#include "tagsfm/recon/reconstructor.h"
#include "tagsfm/synth/box_scene.h"

namespace {

double Percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, static_cast<size_t>(q * static_cast<double>(v.size())))];
}

nlohmann::json Summary(const std::vector<double>& ms) {
  return {{"p50", Percentile(ms, 0.5)}, {"p95", Percentile(ms, 0.95)}, {"max", Percentile(ms, 1.0)}};
}

nlohmann::json RunMode(const tagsfm::synth::SyntheticScene& scene, double tag_size, bool known_map) {
  tagsfm::TargetConfig targets;
  targets.size_m = tag_size;
  auto recon = tagsfm::Reconstructor::Create(scene.camera, targets,
                                             known_map ? std::optional<tagsfm::TargetCornerMap>(scene.targets)
                                                       : std::nullopt,
                                             {});
  std::vector<double> ms, cpu_ms, keyframe_ms, other_ms;
  int registered = 0;
  for (const auto& detections : scene.detections) {
    const auto t0 = std::chrono::steady_clock::now();
    const double c0 = tagsfm::ThreadCpuMs();
    const auto report = (*recon)->AddFrame(detections);
    cpu_ms.push_back(tagsfm::ThreadCpuMs() - c0);
    ms.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
    registered += report.registered;
    (report.keyframe ? keyframe_ms : other_ms).push_back(ms.back());
  }
  const auto t0 = std::chrono::steady_clock::now();
  const auto result = (*recon)->Finish();
  const double finish_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const size_t n = ms.size();
  auto slice = [n](const std::vector<double>& v, size_t from, size_t to) {
    return std::vector<double>(v.begin() + static_cast<long>(std::min(from, n)),
                               v.begin() + static_cast<long>(std::min(to, n)));
  };
  return {{"frame_latency_ms", Summary(ms)},
          {"p95_frames_100_200_ms", Percentile(slice(ms, 100, 200), 0.95)},
          {"p95_frames_900_1000_ms", Percentile(slice(ms, 900, 1000), 0.95)},
          {"frame_cpu_ms", Summary(cpu_ms)},
          {"keyframes", keyframe_ms.size()},
          {"keyframe_latency_ms", Summary(keyframe_ms)},
          {"other_frame_latency_ms", Summary(other_ms)},
          {"cpu_p95_frames_100_200_ms", Percentile(slice(cpu_ms, 100, 200), 0.95)},
          {"cpu_p95_frames_900_1000_ms", Percentile(slice(cpu_ms, 900, 1000), 0.95)},
          {"registered_frames", registered},
          {"targets_mapped", result.tags.size()},
          {"tags_remapped", result.tags_remapped},
          {"outlier_observations", result.outlier_observations},
          {"reprojection_rms_px", result.reprojection_rms_px},
          {"finish_s", finish_s},
          {"global_adjustment_s", result.global_adjustment_s},
          {"covariance_s", result.covariance_s}};
}

}  // namespace

int main(int argc, char** argv) {
  tagsfm::synth::SyntheticSceneOptions options;
  const int frames = argc > 1 ? std::max(300, std::atoi(argv[1])) : 1000;
  options.tags = 110;  // ~22 per face: a view of one or two faces sees ~30
  options.smooth_path = true;
  options.noise_px = 0.1;
  // The camera goes 300 degrees around the box in the first frames - 200,
  // then over its first 200 frames' views again (an operator going back to
  // where the capture began): frames 900-1000 see what frames 100-200 saw,
  // so their cost differs only by the 800 frames of history between them.
  options.frames = frames - 200;
  options.arc_deg = 300 * (frames - 200) / 800.0;
  tagsfm::synth::SyntheticScene scene = tagsfm::synth::MakeSyntheticBoxScene(options);
  for (int i = 0; i < 200; ++i) {
    tagsfm::DetectionSet again = scene.detections[static_cast<size_t>(i)];
    again.frame = options.frames + i;
    scene.detections.push_back(again);
  }
  double in_view = 0;
  for (const auto& d : scene.detections) in_view += static_cast<double>(d.tags.size());
  nlohmann::json out;
  out["benchmark"] = "recon_latency";
  out["frames"] = scene.detections.size();
  out["image"] = std::to_string(options.width) + "x" + std::to_string(options.height);
  out["mean_tags_in_view"] = in_view / static_cast<double>(scene.detections.size());
  out["hardware_threads"] = std::thread::hardware_concurrency();
  const std::string only = argc > 2 ? argv[2] : "";
  if (only.empty() || only == "known_map") out["known_map"] = RunMode(scene, options.tag_size_m, true);
  if (only.empty() || only == "no_map") out["no_map"] = RunMode(scene, options.tag_size_m, false);
  out["peak_rss_mb"] = tagsfm::PeakRssMb();
  double load = 0;
  if (FILE* f = std::fopen("/proc/loadavg", "r")) {
    if (std::fscanf(f, "%lf", &load) != 1) load = 0;
    std::fclose(f);
  }
  out["load_average_1min"] = load;  // others' work on the machine inflates the wall-clock figures
  std::printf("%s\n", out.dump(2).c_str());
  return 0;
}
