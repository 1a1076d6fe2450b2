#pragma once
// The result files of a replay (docs: interface.md, "Results of a replay"),
// each written to a temporary name and renamed into place:
//   poses.csv, targets.csv, report.json, cloud.ply, colmap/{cameras,images,
//   points3D}.txt, preview.png, and targets_cov.csv (this module's addition:
//   the learned targets' joint pose covariance, read by `tagsfm measure`).
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "tagsfm/core/result.h"
#include "tagsfm/recon/reconstruction.h"

namespace tagsfm {

// What the driver (replay, the daemon) measured around the reconstruction.
struct RunStats {
  int frames = 0;                       // frames in the input
  int frames_skipped = 0;               // unreadable images, skipped
  std::vector<std::pair<FrameId, std::string>> skipped;  // frame, why
  double runtime_s = 0;
  std::vector<double> frame_latency_ms; // reconstruction per frame, detection aside
  std::vector<double> detection_ms;     // detection per frame
  std::string tag_search;               // "tracking", "every_frame" (empty: not reported)
  int full_frame_detections = 0;        // frames detected in full (scheduled, first, after a lost tag)
  int tag_search_recoveries = 0;        // of those, after a tracked tag was not where predicted
  std::vector<double> feature_ms;       // feature tracking per feature keyframe
  double triangulation_s = 0;           // feature points from the final poses
  double peak_rss_mb = 0;
  std::map<FrameId, std::string> image_names;  // for colmap/images.txt
  std::string mode;                     // "known map", "no map", ...
};

Status WriteReport(const std::filesystem::path& path, const ReconstructionResult& result, const RunStats& stats);
Status WriteCloudPly(const std::filesystem::path& path, const ReconstructionResult& result);
Status WriteColmapModel(const std::filesystem::path& dir, const ReconstructionResult& result, const RunStats& stats);
Status WritePreview(const std::filesystem::path& path, const ReconstructionResult& result);
Status WriteTargetCovariance(const std::filesystem::path& path, const TagCovariance& covariance);
Result<TagCovariance> ReadTargetCovariance(const std::filesystem::path& path);

// All of the above into OUT (created if needed).
Status WriteResults(const std::filesystem::path& out_dir, const ReconstructionResult& result, const RunStats& stats);

// Peak resident memory of this process (VmHWM), in MB; 0 if unknown.
double PeakRssMb();

// Per-corner reprojection figures of a result: RMS error (px) and number of
// frames, keyed by (tag, corner).
struct CornerStats {
  double rms_px = 0;
  int track_length = 0;
};
std::map<std::pair<TagId, int>, CornerStats> ComputeCornerStats(const ReconstructionResult& result);

}  // namespace tagsfm
