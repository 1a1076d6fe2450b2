// eval's PLY reader (ascii and both binary encodings).
#include "fuzz_file.h"
#include "tagsfm/eval/ply_reader.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto path = tagsfm::fuzz::WriteInput("cloud.ply", data, size);
  (void)tagsfm::eval::ReadPlyPoints(path);
  return 0;
}
