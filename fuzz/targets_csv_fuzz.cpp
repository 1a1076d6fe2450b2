// targets.csv (the known target map) and poses.csv: the contract's CSV readers.
#include "fuzz_file.h"
#include "tagsfm/core/csv_formats.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto path = tagsfm::fuzz::WriteInput("targets.csv", data, size);
  (void)tagsfm::ReadTargetsCsv(path);
  (void)tagsfm::ReadPosesCsv(path);
  return 0;
}
