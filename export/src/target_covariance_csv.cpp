#include "tagsfm/export/target_covariance_csv.h"

#include <map>
#include <sstream>
#include <vector>

#include "tagsfm/core/file_util.h"
#include "tagsfm/core/number_text.h"

namespace tagsfm {

Status WriteTargetCovariance(const std::filesystem::path& path, const TagCovariance& cov) {
  std::ostringstream out;
  out << "tag_a,tag_b";
  for (int r = 0; r < 6; ++r) {
    for (int c = 0; c < 6; ++c) out << ",c" << r << c;
  }
  out << "\n";
  for (size_t a = 0; a < cov.ids.size(); ++a) {
    for (size_t b = a; b < cov.ids.size(); ++b) {
      out << cov.ids[a] << "," << cov.ids[b];
      for (int r = 0; r < 6; ++r) {
        for (int c = 0; c < 6; ++c) {
          out << "," << ExactText(cov.covariance(static_cast<Eigen::Index>(6 * a + r), static_cast<Eigen::Index>(6 * b + c)));
        }
      }
      out << "\n";
    }
  }
  return WriteFileAtomically(path, out.str());
}

Result<TagCovariance> ReadTargetCovariance(const std::filesystem::path& path) {
  auto text = ReadFileToString(path);
  if (!text) return text.error();
  std::istringstream in(*text);
  std::string line;
  std::vector<std::pair<std::pair<TagId, TagId>, std::vector<double>>> rows;
  std::map<TagId, int> index;
  int line_number = 0;
  while (std::getline(in, line)) {
    ++line_number;
    if (line_number == 1 || line.find_first_not_of(" \r\t") == std::string::npos) continue;
    const auto fields = SplitCsvLine(line);
    const std::string where = path.string() + ":" + std::to_string(line_number) + ": ";
    if (fields.size() != 38) return MakeError(where + "expected 38 fields, found " + std::to_string(fields.size()));
    long long a = 0, b = 0;
    if (!ParseInt64(fields[0], &a) || !ParseInt64(fields[1], &b)) return MakeError(where + "tag ids must be integers");
    std::vector<double> values(36);
    for (int i = 0; i < 36; ++i) {
      if (!ParseDouble(fields[2 + i], &values[i])) return MakeError(where + "field " + std::to_string(i + 3) + " is not a number");
    }
    index.emplace(static_cast<TagId>(a), 0);
    index.emplace(static_cast<TagId>(b), 0);
    rows.push_back({{static_cast<TagId>(a), static_cast<TagId>(b)}, std::move(values)});
  }
  TagCovariance cov;
  for (auto& [id, i] : index) {
    i = static_cast<int>(cov.ids.size());
    cov.ids.push_back(id);
  }
  const int n = 6 * static_cast<int>(cov.ids.size());
  cov.covariance = Eigen::MatrixXd::Zero(n, n);
  for (const auto& [ids, values] : rows) {
    const int a = index[ids.first], b = index[ids.second];
    for (int r = 0; r < 6; ++r) {
      for (int c = 0; c < 6; ++c) {
        cov.covariance(6 * a + r, 6 * b + c) = values[6 * r + c];
        cov.covariance(6 * b + c, 6 * a + r) = values[6 * r + c];
      }
    }
  }
  return cov;
}

}  // namespace tagsfm
