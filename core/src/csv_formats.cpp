#include "tagsfm/core/csv_formats.h"

#include <fstream>
#include <set>
#include <sstream>
#include <string>

#include "tagsfm/core/file_util.h"
#include "tagsfm/core/number_text.h"

namespace tagsfm {
namespace {

// Reads a CSV with a header row whose first fields must be `expected`;
// calls `row` with the fields of each data row and its 1-based line number.
template <class RowFn>
Status ReadCsv(const std::filesystem::path& path, const std::vector<std::string>& expected, RowFn row) {
  std::ifstream in(path);
  if (!in) return MakeError(path.string() + ": cannot open");
  std::string line;
  if (!std::getline(in, line)) return MakeError(path.string() + ": empty file, expected a header row");
  const auto header = SplitCsvLine(line);
  for (size_t i = 0; i < expected.size(); ++i) {
    if (i >= header.size() || header[i] != expected[i]) {
      return MakeError(path.string() + ":1: header column " + std::to_string(i + 1) + " must be '" + expected[i] + "'");
    }
  }
  int line_number = 1;
  while (std::getline(in, line)) {
    ++line_number;
    if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
    const auto fields = SplitCsvLine(line);
    if (fields.size() < expected.size()) {
      return MakeError(path.string() + ":" + std::to_string(line_number) + ": expected " +
                       std::to_string(expected.size()) + " fields, found " + std::to_string(fields.size()));
    }
    Status status = row(fields, line_number);
    if (!status) return MakeError(path.string() + ":" + std::to_string(line_number) + ": " + status.error().message);
  }
  return Status::Ok();
}

Status ParseDoubles(const std::vector<std::string>& fields, const std::vector<std::string>& names, size_t first,
                    double* out) {
  for (size_t i = first; i < names.size(); ++i) {
    if (!ParseDouble(fields[i], &out[i - first])) return MakeError("field '" + names[i] + "' is not a number: '" + fields[i] + "'");
  }
  return Status::Ok();
}

}  // namespace

Result<TargetCornerMap> ReadTargetsCsv(const std::filesystem::path& path) {
  const std::vector<std::string> names{"tag_id", "corner", "x", "y", "z"};
  std::map<TagId, std::array<bool, 4>> seen;
  TargetCornerMap targets;
  Status status = ReadCsv(path, names, [&](const std::vector<std::string>& f, int) -> Status {
    long long id = 0, corner = 0;
    if (!ParseInt64(f[0], &id)) return MakeError("field 'tag_id' is not an integer: '" + f[0] + "'");
    if (!ParseInt64(f[1], &corner) || corner < 0 || corner > 3) return MakeError("field 'corner' must be 0-3, got '" + f[1] + "'");
    double xyz[3];
    if (Status s = ParseDoubles(f, names, 2, xyz); !s) return s;
    const TagId tag = static_cast<TagId>(id);
    if (seen[tag][corner]) return MakeError("tag " + std::to_string(tag) + " corner " + std::to_string(corner) + " given twice");
    seen[tag][corner] = true;
    targets[tag][corner] = Eigen::Vector3d(xyz[0], xyz[1], xyz[2]);
    return Status::Ok();
  });
  if (!status) return status.error();
  for (const auto& [tag, corners] : seen) {
    for (int c = 0; c < 4; ++c) {
      if (!corners[c]) return MakeError(path.string() + ": tag " + std::to_string(tag) + " lacks corner " + std::to_string(c));
    }
  }
  return targets;
}

Status WriteTargetsCsv(const std::filesystem::path& path, const TargetCornerMap& targets) {
  std::ostringstream out;
  out << "tag_id,corner,x,y,z\n";
  for (const auto& [tag, corners] : targets) {
    for (int c = 0; c < 4; ++c) {
      out << tag << ',' << c << ',' << ExactText(corners[c].x()) << ',' << ExactText(corners[c].y()) << ','
          << ExactText(corners[c].z()) << '\n';
    }
  }
  return WriteFileAtomically(path, out.str());
}

Result<PoseMap> ReadPosesCsv(const std::filesystem::path& path) {
  const std::vector<std::string> names{"frame", "qw", "qx", "qy", "qz", "tx", "ty", "tz"};
  PoseMap poses;
  Status status = ReadCsv(path, names, [&](const std::vector<std::string>& f, int) -> Status {
    long long frame = 0;
    if (!ParseInt64(f[0], &frame)) return MakeError("field 'frame' is not an integer: '" + f[0] + "'");
    double v[7];
    if (Status s = ParseDoubles(f, names, 1, v); !s) return s;
    const Eigen::Quaterniond q(v[0], v[1], v[2], v[3]);
    if (std::abs(q.norm() - 1.0) > 1e-3) return MakeError("quaternion is not of unit length");
    if (poses.count(frame)) return MakeError("frame " + std::to_string(frame) + " given twice");
    poses[frame] = Rigid3d(q, Eigen::Vector3d(v[4], v[5], v[6]));
    return Status::Ok();
  });
  if (!status) return status.error();
  return poses;
}

Status WritePosesCsv(const std::filesystem::path& path, const PoseMap& cam_from_world) {
  std::ostringstream out;
  out << "frame,qw,qx,qy,qz,tx,ty,tz\n";
  for (const auto& [frame, pose] : cam_from_world) {
    const Eigen::Quaterniond& q = pose.rotation;
    out << frame << ',' << ExactText(q.w()) << ',' << ExactText(q.x()) << ',' << ExactText(q.y()) << ','
        << ExactText(q.z()) << ',' << ExactText(pose.translation.x()) << ',' << ExactText(pose.translation.y())
        << ',' << ExactText(pose.translation.z()) << '\n';
  }
  return WriteFileAtomically(path, out.str());
}

}  // namespace tagsfm
