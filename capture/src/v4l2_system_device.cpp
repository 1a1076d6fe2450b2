// The real device node: libv4l2 when the build has it (its plugins still
// apply; its format conversion is switched off because tagsfm decodes the
// camera's own formats, see pixel_decode.h), else the plain system calls.
#include <fcntl.h>
#include <poll.h>
#include <sys/ioctl.h>
#include <sys/mman.h>
#include <unistd.h>

#include <cerrno>

#include "tagsfm/capture/v4l2_device.h"

#ifdef TAGSFM_HAVE_V4L2
#include <libv4l2.h>
#else
namespace {
int v4l2_ioctl(int fd, unsigned long request, void* arg) { return ioctl(fd, request, arg); }
void* v4l2_mmap(void* start, size_t length, int prot, int flags, int fd, int64_t offset) {
  return mmap(start, length, prot, flags, fd, offset);
}
int v4l2_munmap(void* start, size_t length) { return munmap(start, length); }
int v4l2_close(int fd) { return close(fd); }
}  // namespace
#endif

namespace tagsfm {
namespace {

class SystemV4l2Device : public V4l2Device {
 public:
  ~SystemV4l2Device() override { Close(); }

  int Open(const std::string& path) override {
    Close();
    const int fd = open(path.c_str(), O_RDWR | O_NONBLOCK | O_CLOEXEC);
    if (fd < 0) return errno;
#ifdef TAGSFM_HAVE_V4L2
    if (v4l2_fd_open(fd, V4L2_DISABLE_CONVERSION) < 0) {
      const int error = errno;
      close(fd);
      return error;
    }
#endif
    fd_ = fd;
    return 0;
  }

  int Ioctl(unsigned long request, void* arg) override {
    int r;
    do {
      r = v4l2_ioctl(fd_, request, arg);
    } while (r == -1 && errno == EINTR);
    return r == -1 ? errno : 0;
  }

  int Poll(int timeout_ms) override {
    pollfd p{fd_, POLLIN | POLLPRI, 0};
    const int r = poll(&p, 1, timeout_ms);
    if (r < 0) return errno;
    return r == 0 ? ETIMEDOUT : 0;
  }

  void* Map(size_t length, std::int64_t offset) override {
    void* start = v4l2_mmap(nullptr, length, PROT_READ | PROT_WRITE, MAP_SHARED, fd_, offset);
    return start == MAP_FAILED ? nullptr : start;
  }
  void Unmap(void* start, size_t length) override { v4l2_munmap(start, length); }

  void Close() override {
    if (fd_ >= 0) v4l2_close(fd_);
    fd_ = -1;
  }

 private:
  int fd_ = -1;
};

}  // namespace

std::unique_ptr<V4l2Device> MakeSystemV4l2Device() { return std::make_unique<SystemV4l2Device>(); }

}  // namespace tagsfm
