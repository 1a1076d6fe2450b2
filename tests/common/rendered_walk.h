#pragma once
// The rendered walk issue 14's metrology tests share: `tagsfm synth box`,
// 20 frames 1280x720, noise 2, blur 0.7, 0.06 m tags 1.5-3 m away.
#include <filesystem>
#include <sstream>
#include <string>

#include "test_paths.h"

namespace tagsfm::testing {

// The command that renders that walk into `rec`; `options` adds synth
// flags (lens, tag margin, print scale).
inline std::string SynthWalkCommand(const std::filesystem::path& rec, int seed, const std::string& options) {
  std::ostringstream command;
  command << TagsfmExe().string() << " synth box --out " << rec.string()
          << " --frames 20 --width 1280 --height 720 --noise 2 --blur 0.7 --threads 2 --seed " << seed << options;
  return command.str();
}

}  // namespace tagsfm::testing
