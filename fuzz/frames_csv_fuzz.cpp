// frames.csv in a recording whose recording.yaml is valid: Open, then the
// first few frames' loading (files named by the input mostly do not exist).
#include "fuzz_file.h"
#include "tagsfm/capture/recording.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const bool init = [] {
    tagsfm::fuzz::WriteText("recording.yaml",
                            "format: tagsfm-recording/1\ntargets:\n  family: tag36h11\n  size_m: 0.05\n");
    return true;
  }();
  (void)init;
  tagsfm::fuzz::WriteInput("frames.csv", data, size);
  auto reader = tagsfm::RecordingReader::Open(tagsfm::fuzz::FuzzDir());
  if (!reader) return 0;
  for (size_t i = 0; i < reader->entries().size() && i < 3; ++i) (void)reader->LoadFrame(i);
  return 0;
}
