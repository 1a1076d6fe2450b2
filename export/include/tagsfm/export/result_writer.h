#pragma once
// The result files of a replay (docs: interface.md, "Results of a replay"),
// each written to a temporary name and renamed into place:
//   poses.csv, targets.csv, report.json, cloud.ply, features.csv,
//   colmap/{cameras,images,points3D}.txt, preview.png, and targets_cov.csv
//   (the learned targets' joint pose covariance, read by `tagsfm measure`).
#include <filesystem>

#include "tagsfm/core/result.h"
#include "tagsfm/export/run_stats.h"
#include "tagsfm/recon/reconstruction.h"

namespace tagsfm {

Status WriteReport(const std::filesystem::path& path, const ReconstructionResult& result, const RunStats& stats);
Status WriteCloudPly(const std::filesystem::path& path, const ReconstructionResult& result);
Status WriteColmapModel(const std::filesystem::path& dir, const ReconstructionResult& result, const RunStats& stats);
Status WritePreview(const std::filesystem::path& path, const ReconstructionResult& result);

// All of the above into OUT (created if needed).
Status WriteResults(const std::filesystem::path& out_dir, const ReconstructionResult& result, const RunStats& stats);

}  // namespace tagsfm
