// recording.yaml: ReadRecordingYaml and, on the same bytes, the camera and
// targets blocks as the daemon's config reads them.
#include "fuzz_file.h"
#include "tagsfm/capture/recording.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto path = tagsfm::fuzz::WriteInput("recording.yaml", data, size);
  auto info = tagsfm::ReadRecordingYaml(path);
  if (info) (void)tagsfm::RecordingYamlText(*info);
  (void)tagsfm::ReadCameraAndTargets(path);
  return 0;
}
