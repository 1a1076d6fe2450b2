#pragma once
// The few calls a V4L2 capture makes on a device node, behind an interface
// so that the streaming logic can be tested against a scripted device (buffer
// cycling, EAGAIN, a camera unplugged mid-stream) without a kernel driver.
// The system device goes through libv4l2 (with its format conversion off:
// tagsfm negotiates and decodes the camera's own formats) or, in a build
// without libv4l2, through plain open/ioctl/mmap.
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>

#include "tagsfm/capture/capture_settings.h"
#include "tagsfm/capture/frame_source.h"

namespace tagsfm {

class V4l2Device {
 public:
  virtual ~V4l2Device() = default;
  // Each call returns 0 or an errno value (never -1 with errno set).
  virtual int Open(const std::string& path) = 0;
  virtual int Ioctl(unsigned long request, void* arg) = 0;  // EINTR already retried
  // Waits until a buffer can be dequeued (or an error is pending): 0, or
  // ETIMEDOUT after `timeout_ms`, or another errno value.
  virtual int Poll(int timeout_ms) = 0;
  virtual void* Map(size_t length, std::int64_t offset) = 0;  // nullptr on failure
  virtual void Unmap(void* start, size_t length) = 0;
  virtual void Close() = 0;
};

std::unique_ptr<V4l2Device> MakeSystemV4l2Device();

// v4l2:PATH on `device`: negotiates the format (capture.pixel_format, or the
// best the camera offers for grey or colour frames), applies the camera
// controls of `settings`, and streams.
Result<std::unique_ptr<FrameSource>> OpenV4l2FrameSource(const std::string& path, std::unique_ptr<V4l2Device> device,
                                                          const CaptureSettings& settings);

}  // namespace tagsfm
