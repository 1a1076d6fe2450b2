#include "tagsfm/detect/apriltag_worker_pool.h"

#include <cstdint>

#include <apriltag/apriltag.h>

namespace tagsfm {

void StartAprilTagWorkerPool(apriltag_detector* detector) {
  if (detector == nullptr || detector->nthreads <= 1) return;
  // 3 x 3 at decimation 1: no threshold tile, no component, no quad, so no
  // task; larger images (16 x 16 measured) give tasks and keep the race.
  // Three runs: each needs every thread to pass its wait once more.
  std::uint8_t pixels[9] = {128, 128, 128, 128, 128, 128, 128, 128, 128};
  image_u8_t image{3, 3, 3, pixels};
  const float decimate = detector->quad_decimate;
  detector->quad_decimate = 1.0f;
  for (int run = 0; run < 3; ++run) apriltag_detections_destroy(apriltag_detector_detect(detector, &image));
  detector->quad_decimate = decimate;
}

}  // namespace tagsfm
