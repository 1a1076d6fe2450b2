#pragma once
// The known target map a run starts from: a file given on the command line,
// or the one `targets.map` names, relative to the file that names it (the
// recording's recording.yaml, or the run config).
#include <filesystem>
#include <optional>
#include <string>

#include "tagsfm/capture/recording.h"

namespace tagsfm {

// `override_file` (may be empty) wins over info.targets.map. No map: nullopt.
Result<std::optional<TargetCornerMap>> ResolveTargetMap(const RecordingInfo& info, const std::filesystem::path& named_in_dir,
                                                        const std::string& override_file);

}  // namespace tagsfm
