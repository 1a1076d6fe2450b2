#include "tagsfm/pipeline/target_map.h"

#include "tagsfm/core/csv_formats.h"

namespace tagsfm {

Result<std::optional<TargetCornerMap>> ResolveTargetMap(const RecordingInfo& info, const std::filesystem::path& named_in_dir,
                                                        const std::string& override_file) {
  std::filesystem::path file = override_file;
  if (file.empty()) {
    if (info.targets.map.empty()) return std::optional<TargetCornerMap>();
    file = info.targets.map;
    if (file.is_relative()) file = named_in_dir / file;
  }
  auto map = ReadTargetsCsv(file);
  if (!map) return map.error();
  return std::optional<TargetCornerMap>(std::move(*map));
}

}  // namespace tagsfm
