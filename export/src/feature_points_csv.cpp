#include "tagsfm/export/feature_points_csv.h"

#include <fstream>
#include <sstream>

#include "tagsfm/core/file_util.h"
#include "tagsfm/core/number_text.h"

namespace tagsfm {
namespace {

constexpr const char* kHeader =
    "point_id,x,y,z,r,g,b,track_length,reprojection_rms_px,cov_xx,cov_xy,cov_xz,cov_yy,cov_yz,cov_zz";

}  // namespace

Status WriteFeaturePointsCsv(const std::filesystem::path& path, const std::vector<FeaturePoint>& points,
                             long long first_id) {
  std::ostringstream out;
  out << kHeader << "\n";
  for (size_t i = 0; i < points.size(); ++i) {
    const FeaturePoint& p = points[i];
    const Eigen::Matrix3d& c = p.covariance;
    out << first_id + static_cast<long long>(i) << ',' << ExactText(p.position.x()) << ',' << ExactText(p.position.y())
        << ',' << ExactText(p.position.z()) << ',' << int{p.rgb[0]} << ',' << int{p.rgb[1]} << ',' << int{p.rgb[2]}
        << ',' << p.observations.size() << ',' << ExactText(p.reprojection_rms_px) << ',' << ExactText(c(0, 0)) << ','
        << ExactText(c(0, 1)) << ',' << ExactText(c(0, 2)) << ',' << ExactText(c(1, 1)) << ',' << ExactText(c(1, 2))
        << ',' << ExactText(c(2, 2)) << '\n';
  }
  return WriteFileAtomically(path, out.str());
}

Result<std::map<long long, StoredFeaturePoint>> ReadFeaturePointsCsv(const std::filesystem::path& path) {
  std::ifstream in(path);
  if (!in) return MakeError(path.string() + ": cannot open");
  std::string line;
  if (!std::getline(in, line) || line != kHeader) return MakeError(path.string() + ":1: header must be '" + std::string(kHeader) + "'");
  std::map<long long, StoredFeaturePoint> points;
  int line_number = 1;
  while (std::getline(in, line)) {
    ++line_number;
    if (line.empty()) continue;
    const std::vector<std::string> fields = SplitCsvLine(line);
    const std::string where = path.string() + ":" + std::to_string(line_number) + ": ";
    if (fields.size() != 15) return MakeError(where + "expected 15 fields, got " + std::to_string(fields.size()));
    double v[15];
    for (int k = 0; k < 15; ++k) {
      if (!ParseDouble(fields[static_cast<size_t>(k)], &v[k])) return MakeError(where + "field " + std::to_string(k + 1) + " is not a number");
    }
    StoredFeaturePoint p;
    p.position = Eigen::Vector3d(v[1], v[2], v[3]);
    p.track_length = static_cast<int>(v[7]);
    p.reprojection_rms_px = v[8];
    p.covariance << v[9], v[10], v[11], v[10], v[12], v[13], v[11], v[13], v[14];
    points[static_cast<long long>(v[0])] = p;
  }
  return points;
}

}  // namespace tagsfm
