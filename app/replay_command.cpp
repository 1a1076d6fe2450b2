// tagsfm replay REC --out OUT: the whole pipeline on a recording, as the live
// daemon would run it, frame by frame: read, detect tags, reconstruct; then
// the final adjustment and the result files (docs/recon.md). With
// --realtime, frames are paced at their timestamps and the live feedback is
// served on the dashboard, as `run` serves it, so that a recording can be
// watched (or a dashboard tried) without a camera; the results are the same.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <spdlog/spdlog.h>

#include "command_registry.h"
#include "feature_pipeline.h"
#include "replay_support.h"
#include "tagsfm/capture/recording.h"
#include "tagsfm/capture/timestamp_pacer.h"
#include "tagsfm/dashboard/dashboard_server.h"
#include "tagsfm/feedback/live_feedback.h"
#include "tagsfm/recon/camera_calibration.h"
#include "tagsfm/recon/reconstructor.h"
#include "tagsfm/recon/result_writer.h"

namespace tagsfm {
namespace {

struct ReplayArgs {
  std::string recording;
  std::string out;
  std::string targets;
  bool no_features = false;
  bool no_targets = false;
  bool realtime = false;
  std::string dashboard = "127.0.0.1:8080";
  std::string tag_search = TagSearchName(TagSearch::kTracking);
};

double MsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

// The q-quantile of `values` (0 when empty).
double Percentile(std::vector<double> values, double q) {
  if (values.empty()) return 0.0;
  const size_t i = std::min(values.size() - 1, static_cast<size_t>(q * static_cast<double>(values.size())));
  std::nth_element(values.begin(), values.begin() + static_cast<long>(i), values.end());
  return values[i];
}

void PrintSummary(const ReconstructionResult& result, const RunStats& stats, const std::string& out) {
  int registered = 0;
  for (const auto& f : result.frames) registered += f.registered;
  std::fprintf(stderr,
               "\n  frames       %d read, %d skipped (unreadable)\n"
               "  registered   %d of %d frames\n"
               "  targets      %zu in the map (%s)\n"
               "  features     %zu points triangulated from the final poses\n"
               "  reprojection %.3f px RMS over %d target corner observations\n"
               "  per frame    %.2f ms p50, %.2f ms p95 (detection aside)\n"
               "  detection    %.2f ms p50 per frame, %s (%d of the frames in full, %d after a lost tag)\n"
               "  runtime      %.1f s, peak memory %.0f MB\n"
               "  results in   %s  (poses.csv, targets.csv, report.json, cloud.ply, colmap/, preview.png)\n\n",
               stats.frames, stats.frames_skipped, registered, stats.frames - stats.frames_skipped,
               result.tags.size(), stats.mode.c_str(), result.feature_points.size(), result.reprojection_rms_px, result.observations,
               Percentile(stats.frame_latency_ms, 0.5), Percentile(stats.frame_latency_ms, 0.95),
               Percentile(stats.detection_ms, 0.5),
               stats.tag_search.c_str(), stats.full_frame_detections, stats.tag_search_recoveries,
               stats.runtime_s, stats.peak_rss_mb, out.c_str());
}

int RunReplay(const ReplayArgs& args) {
  const auto start = std::chrono::steady_clock::now();
  if (args.no_targets) {
    spdlog::error("--no-targets (feature SfM alone) is not available yet: this build reconstructs from targets only");
    return 2;
  }
  auto reader = RecordingReader::Open(args.recording);
  if (!reader) {
    spdlog::error("{}", reader.error().message);
    return 1;
  }
  for (const auto& warning : reader->warnings()) spdlog::warn("{}", warning);
  const RecordingInfo& info = reader->info();

  std::optional<TargetCornerMap> known_map;
  std::string mode = "no map: targets learned, scale from the tag size";
  if (!args.targets.empty()) {
    auto map = ReadTargetsCsv(args.targets);
    if (!map) {
      spdlog::error("{}", map.error().message);
      return 1;
    }
    known_map = std::move(*map);
  } else {
    auto map = reader->LoadTargetMap();
    if (!map) {
      spdlog::error("{}", map.error().message);
      return 1;
    }
    known_map = std::move(*map);
  }
  if (known_map && !known_map->empty()) mode = "known map (" + std::to_string(known_map->size()) + " targets held fixed)";

  auto search = ParseTagSearch(args.tag_search);
  if (!search) {
    spdlog::error("--tag-search: {}", search.error().message);
    return 2;
  }
  auto tracker = TagSearchForRecording(info, *search);
  if (!tracker) {
    spdlog::error("recording.yaml: targets.family: {}", tracker.error().message);
    return 1;
  }

  const auto& entries = reader->entries();
  RunStats stats;
  stats.frames = static_cast<int>(entries.size());
  stats.mode = mode;
  std::optional<Frame> last_frame;  // the frame detect() read last, for the features
  // Once reconstruction runs, it tells the tracker where the mapped tags
  // will be (Reconstructor::PredictTagCorners), as `run` does.
  std::function<std::map<TagId, QuadCorners>(FrameId)> predict = [](FrameId) { return std::map<TagId, QuadCorners>{}; };
  auto detect = [&](size_t i, int* width, int* height) -> std::optional<DetectionSet> {
    last_frame.reset();
    auto frame = reader->LoadFrame(i);
    if (!frame) {
      spdlog::warn("skipping frame {}: {}", entries[i].frame, frame.error().message);
      ++stats.frames_skipped;
      stats.skipped.emplace_back(entries[i].frame, frame.error().message);
      return std::nullopt;
    }
    stats.image_names[entries[i].frame] = entries[i].file.filename().string();
    if (width) *width = frame->gray.cols;
    if (height) *height = frame->gray.rows;
    const auto t0 = std::chrono::steady_clock::now();
    auto detections = (*tracker)->Track(frame->gray, entries[i].frame, predict(entries[i].frame));
    stats.detection_ms.push_back(MsSince(t0));
    if (!detections) {
      spdlog::warn("skipping frame {}: {}", entries[i].frame, detections.error().message);
      ++stats.frames_skipped;
      stats.skipped.emplace_back(entries[i].frame, detections.error().message);
      return std::nullopt;
    }
    last_frame = std::move(*frame);
    return std::move(*detections);
  };

  // Without a camera block the intrinsics come from the targets first.
  std::vector<std::optional<DetectionSet>> cached;
  CameraModel camera;
  if (info.camera) {
    camera = *info.camera;
  } else {
    ProgressLine progress("detect", entries.size());
    int width = 0, height = 0;
    for (size_t i = 0; i < entries.size(); ++i) {
      cached.push_back(detect(i, &width, &height));
      progress.Update(i + 1);
    }
    progress.Done();
    std::vector<DetectionSet> sets;
    for (const auto& c : cached) {
      if (c) sets.push_back(*c);
    }
    auto calibration = CalibrateFromTargets(sets, info.targets, width, height, known_map, {});
    if (!calibration) {
      spdlog::error("{}: no camera block, and {}", (reader->dir() / "recording.yaml").string(),
                    calibration.error().message);
      return 1;
    }
    camera = calibration->camera;
    spdlog::info("no camera block: calibrated from {} tag views, fx {:.1f} fy {:.1f} cx {:.1f} cy {:.1f}, {:.3f} px RMS",
                 calibration->views, camera.fx, camera.fy, camera.cx, camera.cy, calibration->rms_px);
  }

  ReconstructorOptions options;
  options.refine_intrinsics = !info.camera.has_value();  // calibrated here: the final adjustment refines it
  auto recon = Reconstructor::Create(camera, info.targets, known_map, options);
  if (!recon) {
    spdlog::error("{}: {}", (reader->dir() / "recording.yaml").string(), recon.error().message);
    return 1;
  }
  if (*search == TagSearch::kTracking) {
    predict = [&](FrameId frame) { return (*recon)->PredictTagCorners(frame); };
  }
  // Realtime: the dashboard and the live feedback, as `run` has them.
  std::unique_ptr<DashboardServer> dashboard;
  std::optional<LiveFeedback> feedback;
  TimestampPacer pacer;
  if (args.realtime) {
    auto server = DashboardServer::Start(args.dashboard);
    if (!server) {
      spdlog::error("--dashboard: {}", server.error().message);
      return 1;
    }
    dashboard = std::move(*server);
    feedback.emplace(camera, info.targets, LiveFeedbackOptions{});
    spdlog::info("dashboard at {}; replaying at the recording's pace", dashboard->url());
  }

  std::unique_ptr<FeaturePipeline> features;
  if (!args.no_features) {
    auto pipeline = FeaturePipeline::Create(camera, info.targets, {});
    if (!pipeline) {
      spdlog::error("{}", pipeline.error().message);
      return 1;
    }
    features = std::move(*pipeline);
  }

  ProgressLine progress("replay", entries.size());
  for (size_t i = 0; i < entries.size(); ++i) {
    if (args.realtime) pacer.WaitFor(entries[i].timestamp_ns);
    std::optional<DetectionSet> detections = cached.empty() ? detect(i, nullptr, nullptr) : std::move(cached[i]);
    if (detections) {
      const auto t0 = std::chrono::steady_clock::now();
      const FrameReport report = (*recon)->AddFrame(*detections);
      stats.frame_latency_ms.push_back(MsSince(t0));
      if (features && features->SelectKeyframe(*detections, report)) {
        if (!last_frame) {  // calibrated first: the frame was read before
          auto frame = reader->LoadFrame(i);
          if (frame) last_frame = std::move(*frame);
        }
        if (last_frame) {
          const auto t1 = std::chrono::steady_clock::now();
          if (Status s = features->Track(last_frame->gray, last_frame->image, *detections); !s) {
            spdlog::warn("frame {}: features: {}", entries[i].frame, s.error().message);
          }
          stats.feature_ms.push_back(MsSince(t1));
        }
      }
      if (feedback) dashboard->Publish(LiveStatusJson(feedback->Update(*detections, report, entries[i].timestamp_ns)));
    }
    progress.Update(i + 1);
  }
  progress.Done();
  if (pacer.late_frames() > 0) {
    spdlog::warn("{} frames were processed more than 100 ms after their time: this machine is slower than the "
                 "recording's frame rate (a live run would have dropped frames from live feedback)",
                 pacer.late_frames());
  }
  ReconstructionResult result = (*recon)->Finish();
  if (features) {
    const auto t0 = std::chrono::steady_clock::now();
    result.feature_points = features->Triangulate(result.Poses(), result.camera);
    stats.triangulation_s = MsSince(t0) / 1000.0;
  }
  stats.tag_search = TagSearchName(*search);
  stats.full_frame_detections = (*tracker)->stats().full_frame_detections;
  stats.tag_search_recoveries = (*tracker)->stats().recoveries;
  stats.runtime_s = MsSince(start) / 1000.0;
  stats.peak_rss_mb = PeakRssMb();
  if (dashboard) dashboard->Stop();
  if (Status s = WriteResults(args.out, result, stats); !s) {
    spdlog::error("{}", s.error().message);
    return 1;
  }
  // Progress is for terminals only; the summary is for everyone (the
  // README's main job prints it, also into a log).
  PrintSummary(result, stats, args.out);
  return 0;
}

void AddReplayCommand(CLI::App& app, int& exit_code) {
  auto args = std::make_shared<ReplayArgs>();
  CLI::App* cmd = app.add_subcommand("replay", "run the pipeline on a recording and write the results");
  cmd->add_option("recording", args->recording, "recording folder (recording.yaml, frames.csv, frames/)")->required();
  cmd->add_option("--out", args->out, "output folder for the results")->required();
  cmd->add_option("--targets", args->targets, "known target map (targets.csv), overriding the recording's");
  cmd->add_flag("--no-features", args->no_features, "targets only (photogrammetry alone): no SIFT feature points");
  cmd->add_flag("--no-targets", args->no_targets, "feature SfM alone (not available yet)");
  cmd->add_option("--tag-search", args->tag_search,
                  "tracking (video: regions around the tags of the frames before, full frames every 15) or "
                  "every_frame (photo sets: a full-frame detection on each)")
      ->capture_default_str();
  cmd->add_flag("--realtime", args->realtime, "pace frames at their timestamps and serve the live dashboard, like run");
  cmd->add_option("--dashboard", args->dashboard, "with --realtime: serve the dashboard at ADDR:PORT (port 0: any free one)")
      ->capture_default_str();
  cmd->callback([args, &exit_code] { exit_code = RunReplay(*args); });
}

const bool kRegistered = RegisterCommand("replay", &AddReplayCommand);

}  // namespace
}  // namespace tagsfm
