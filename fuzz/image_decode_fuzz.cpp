// A recorded frame's file: LoadImageFrame (header size check, decode,
// truncation check, grey). OpenCV's own pixel limit (OPENCV_IO_MAX_IMAGE_PIXELS)
// is read when its library loads, before any fuzzer hook runs: setting it
// here had no effect, and a 44-byte JPEG claiming 1 Gpx found that
// (docs/reliability.md, finding 5). LoadImageFrame now reads the size from
// the header and refuses what no frame can be.
#include "fuzz_file.h"
#include "tagsfm/capture/recording.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto path = tagsfm::fuzz::WriteInput("frame.img", data, size);
  (void)tagsfm::LoadImageFrame(path, 0, 0);
  return 0;
}
