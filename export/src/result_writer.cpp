#include "tagsfm/export/result_writer.h"

#include <future>

#include "tagsfm/export/feature_points_csv.h"
#include "tagsfm/export/target_covariance_csv.h"

namespace tagsfm {

Status WriteResults(const std::filesystem::path& out_dir, const ReconstructionResult& result, const RunStats& stats) {
  std::error_code ec;
  std::filesystem::create_directories(out_dir, ec);
  if (ec) return MakeError(out_dir.string() + ": cannot create the output folder (" + ec.message() + ")");
  // The COLMAP model (every point's track, as text) on a thread of its own
  // beside the other files: the two largest writes overlap. report.json,
  // which says the run is complete, comes last.
  std::future<Status> colmap =
      std::async(std::launch::async, [&] { return WriteColmapModel(out_dir / "colmap", result, stats); });
  const Status others = [&]() -> Status {
    if (Status s = WritePosesCsv(out_dir / "poses.csv", result.Poses()); !s) return s;
    if (Status s = WriteTargetsCsv(out_dir / "targets.csv", result.Targets()); !s) return s;
    if (Status s = WriteCloudPly(out_dir / "cloud.ply", result); !s) return s;
    if (Status s = WriteFeaturePointsCsv(out_dir / "features.csv", result.feature_points, kFirstFeaturePointId); !s) return s;
    std::error_code remove_ec;
    if (result.covariance) {
      if (Status s = WriteTargetCovariance(out_dir / "targets_cov.csv", *result.covariance); !s) return s;
    } else {
      std::filesystem::remove(out_dir / "targets_cov.csv", remove_ec);
    }
    return WritePreview(out_dir / "preview.png", result);
  }();
  const Status colmap_written = colmap.get();
  if (!others) return others;
  if (!colmap_written) return colmap_written;
  return WriteReport(out_dir / "report.json", result, stats);
}

}  // namespace tagsfm
