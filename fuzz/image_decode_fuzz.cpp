// A recorded frame's file: LoadImageFrame (decode, truncation check, grey).
#include <cstdlib>

#include "fuzz_file.h"
#include "tagsfm/capture/recording.h"

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  // A header may claim a huge image; OpenCV's decoders allocate what it
  // claims up to this limit (1 Mpx here, 1 Gpx by default).
  setenv("OPENCV_IO_MAX_IMAGE_PIXELS", "1048576", 1);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto path = tagsfm::fuzz::WriteInput("frame.img", data, size);
  (void)tagsfm::LoadImageFrame(path, 0, 0);
  return 0;
}
