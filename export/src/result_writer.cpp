#include "tagsfm/export/result_writer.h"

#include "tagsfm/export/feature_points_csv.h"
#include "tagsfm/export/target_covariance_csv.h"

namespace tagsfm {

Status WriteResults(const std::filesystem::path& out_dir, const ReconstructionResult& result, const RunStats& stats) {
  std::error_code ec;
  std::filesystem::create_directories(out_dir, ec);
  if (ec) return MakeError(out_dir.string() + ": cannot create the output folder (" + ec.message() + ")");
  if (Status s = WritePosesCsv(out_dir / "poses.csv", result.Poses()); !s) return s;
  if (Status s = WriteTargetsCsv(out_dir / "targets.csv", result.Targets()); !s) return s;
  if (Status s = WriteCloudPly(out_dir / "cloud.ply", result); !s) return s;
  if (Status s = WriteFeaturePointsCsv(out_dir / "features.csv", result.feature_points, kFirstFeaturePointId); !s) return s;
  if (Status s = WriteColmapModel(out_dir / "colmap", result, stats); !s) return s;
  if (result.covariance) {
    if (Status s = WriteTargetCovariance(out_dir / "targets_cov.csv", *result.covariance); !s) return s;
  } else {
    std::filesystem::remove(out_dir / "targets_cov.csv", ec);
  }
  if (Status s = WritePreview(out_dir / "preview.png", result); !s) return s;
  return WriteReport(out_dir / "report.json", result, stats);
}

}  // namespace tagsfm
