// eval's COLMAP text readers: the same bytes as cameras.txt, images.txt and
// points3D.txt.
#include "fuzz_file.h"
#include "tagsfm/eval/colmap_model.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto path = tagsfm::fuzz::WriteInput("model.txt", data, size);
  (void)tagsfm::eval::ReadColmapCamerasTxt(path);
  (void)tagsfm::eval::ReadColmapImagesTxt(path);
  (void)tagsfm::eval::ReadColmapPoints3DTxt(path);
  return 0;
}
