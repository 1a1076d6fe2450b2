// The daemon's config file (app/run_config.cpp): capture, camera, targets,
// run and pipeline blocks.
#include "fuzz_file.h"
#include "run_config.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto path = tagsfm::fuzz::WriteInput("config.yaml", data, size);
  (void)tagsfm::ReadRunConfig(path);
  (void)tagsfm::ReadPipelineOptionsFile(path);
  return 0;
}
