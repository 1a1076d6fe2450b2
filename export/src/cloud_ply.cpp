// cloud.ply: binary little-endian, the target corners (4 per tag, tags in
// id order: vertex 4 * i + corner for the i-th tag, which is 4 * tag id +
// corner only when the ids have no gaps) then the feature points, with
// colour, track length and error.
#include <cstdint>
#include <sstream>

#include "corner_stats.h"
#include "tagsfm/core/file_util.h"
#include "tagsfm/export/result_writer.h"

namespace tagsfm {

Status WriteCloudPly(const std::filesystem::path& path, const ReconstructionResult& result) {
  const auto stats = ComputeCornerStats(result);
  std::ostringstream header;
  header << "ply\nformat binary_little_endian 1.0\n"
         << "comment tagsfm: target corners (4 per tag, tags in id order), then feature points\n"
         << "element vertex " << 4 * result.tags.size() + result.feature_points.size() << "\n"
         << "property double x\nproperty double y\nproperty double z\n"
         << "property uchar red\nproperty uchar green\nproperty uchar blue\n"
         << "property int track_length\nproperty float reprojection_error\nend_header\n";
  const std::string head = header.str();
  std::vector<unsigned char> bytes(head.begin(), head.end());
  auto append = [&bytes](const void* data, size_t n) {
    const auto* p = static_cast<const unsigned char*>(data);
    bytes.insert(bytes.end(), p, p + n);  // x86 and ARM rigs are little-endian
  };
  for (const auto& [id, tag] : result.tags) {
    const TagCorners corners = tag.CornersInWorld();
    for (int k = 0; k < 4; ++k) {
      append(corners[k].data(), 3 * sizeof(double));
      // Known targets blue, learned ones orange.
      const unsigned char colour[3] = {static_cast<unsigned char>(tag.known ? 40 : 255),
                                       static_cast<unsigned char>(tag.known ? 90 : 140),
                                       static_cast<unsigned char>(tag.known ? 255 : 0)};
      append(colour, 3);
      auto it = stats.find({id, k});
      const std::int32_t track = it == stats.end() ? 0 : it->second.track_length;
      const float error = it == stats.end() ? 0.0f : static_cast<float>(it->second.rms_px);
      append(&track, sizeof(track));
      append(&error, sizeof(error));
    }
  }
  for (const FeaturePoint& p : result.feature_points) {
    append(p.position.data(), 3 * sizeof(double));
    append(p.rgb.data(), 3);
    const std::int32_t track = static_cast<std::int32_t>(p.observations.size());
    const float error = static_cast<float>(p.reprojection_rms_px);
    append(&track, sizeof(track));
    append(&error, sizeof(error));
  }
  return WriteFileAtomically(path, bytes);
}

}  // namespace tagsfm
