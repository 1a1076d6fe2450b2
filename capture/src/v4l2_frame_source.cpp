// v4l2:/dev/videoN — a V4L2 camera through libv4l2, which converts the
// camera's own pixel format (YUYV, MJPEG, ...) to grey or BGR for us.
#include <fcntl.h>
#include <sys/mman.h>
#include <sys/select.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include <opencv2/core.hpp>

#include "tagsfm/capture/frame_source.h"

#ifdef TAGSFM_HAVE_V4L2
#include <libv4l2.h>
#include <linux/videodev2.h>
#endif

namespace tagsfm {

#ifdef TAGSFM_HAVE_V4L2
namespace {

int Ioctl(int fd, unsigned long request, void* arg) {
  int r;
  do {
    r = v4l2_ioctl(fd, request, arg);
  } while (r == -1 && errno == EINTR);
  return r;
}

class V4l2FrameSource : public FrameSource {
 public:
  V4l2FrameSource(std::string device, CaptureSettings settings) : device_(std::move(device)), settings_(std::move(settings)) {}
  ~V4l2FrameSource() override { Close(); }

  Status Start() {
    fd_ = v4l2_open(device_.c_str(), O_RDWR | O_NONBLOCK, 0);
    if (fd_ < 0) return Fail("cannot open (" + std::string(std::strerror(errno)) + ")");
    v4l2_capability cap{};
    if (Ioctl(fd_, VIDIOC_QUERYCAP, &cap) != 0) return Fail("not a V4L2 device");
    if (!(cap.capabilities & V4L2_CAP_VIDEO_CAPTURE) || !(cap.capabilities & V4L2_CAP_STREAMING)) {
      return Fail("is not a streaming video capture device");
    }
    v4l2_format format{};
    format.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    format.fmt.pix.width = static_cast<unsigned>(settings_.width);
    format.fmt.pix.height = static_cast<unsigned>(settings_.height);
    format.fmt.pix.pixelformat = settings_.colour ? V4L2_PIX_FMT_BGR24 : V4L2_PIX_FMT_GREY;
    format.fmt.pix.field = V4L2_FIELD_NONE;
    if (Ioctl(fd_, VIDIOC_S_FMT, &format) != 0) return Fail("rejects the format (" + std::string(std::strerror(errno)) + ")");
    width_ = static_cast<int>(format.fmt.pix.width);
    height_ = static_cast<int>(format.fmt.pix.height);
    stride_ = static_cast<int>(format.fmt.pix.bytesperline);
    pixel_format_ = format.fmt.pix.pixelformat;
    if (width_ != settings_.width || height_ != settings_.height) {
      warnings_.push_back(device_ + ": asked for " + std::to_string(settings_.width) + "x" + std::to_string(settings_.height) +
                          ", the camera gives " + std::to_string(width_) + "x" + std::to_string(height_));
    }
    SetFrameRate();
    SetControls();
    return StartStreaming();
  }

  Result<std::optional<Frame>> Next() override {
    if (fd_ < 0) return MakeError(device_ + ": camera is closed");
    fd_set fds;
    FD_ZERO(&fds);
    FD_SET(fd_, &fds);
    // A camera that stops delivering for 2 s (or 10 frame times) is gone.
    const double wait_s = std::max(2.0, 10.0 / settings_.fps);
    timeval timeout{static_cast<long>(wait_s), static_cast<long>((wait_s - static_cast<long>(wait_s)) * 1e6)};
    const int ready = select(fd_ + 1, &fds, nullptr, nullptr, &timeout);
    if (ready == 0) return VanishedError("no frame for " + std::to_string(wait_s) + " s");
    if (ready < 0 && errno != EINTR) return VanishedError(std::strerror(errno));
    v4l2_buffer buffer{};
    buffer.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    buffer.memory = V4L2_MEMORY_MMAP;
    if (Ioctl(fd_, VIDIOC_DQBUF, &buffer) != 0) {
      if (errno == EAGAIN) return Next();
      return VanishedError(std::strerror(errno));
    }
    Frame frame;
    frame.index = next_index_++;
    frame.timestamp_ns = static_cast<std::int64_t>(buffer.timestamp.tv_sec) * 1'000'000'000 +
                         static_cast<std::int64_t>(buffer.timestamp.tv_usec) * 1000;
    frame.source = device_;
    const int type = pixel_format_ == V4L2_PIX_FMT_GREY ? CV_8UC1 : CV_8UC3;
    // Copy out of the driver's buffer before handing it back.
    frame.image = cv::Mat(height_, width_, type, buffers_[buffer.index].start, static_cast<size_t>(stride_)).clone();
    frame.gray = ToGray8(frame.image);
    if (Ioctl(fd_, VIDIOC_QBUF, &buffer) != 0) return VanishedError(std::strerror(errno));
    return std::optional<Frame>(std::move(frame));
  }

  const RecordingInfo& info() const override { return info_; }
  std::string uri() const override { return "v4l2:" + device_; }
  std::vector<std::string> TakeWarnings() override { return std::exchange(warnings_, {}); }

 private:
  struct MappedBuffer {
    void* start = nullptr;
    size_t length = 0;
  };

  Error Fail(const std::string& why) {
    Close();
    return MakeError(device_ + ": " + why);
  }
  Error VanishedError(const std::string& why) {
    Close();
    return MakeError(device_ + ": camera stopped delivering frames after frame " + std::to_string(next_index_ - 1) +
                     " (" + why + ")");
  }

  void SetFrameRate() {
    v4l2_streamparm parm{};
    parm.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    parm.parm.capture.timeperframe.numerator = 1000;
    parm.parm.capture.timeperframe.denominator = static_cast<unsigned>(settings_.fps * 1000);
    if (Ioctl(fd_, VIDIOC_S_PARM, &parm) != 0) warnings_.push_back(device_ + ": cannot set the frame rate");
  }

  void SetControl(unsigned id, int value, const char* name) {
    v4l2_control control{};
    control.id = id;
    control.value = value;
    if (Ioctl(fd_, VIDIOC_S_CTRL, &control) != 0) {
      warnings_.push_back(device_ + ": cannot set " + name + " (" + std::strerror(errno) + ")");
    }
  }

  void SetControls() {
    SetControl(V4L2_CID_FOCUS_AUTO, settings_.autofocus ? 1 : 0, "autofocus");
    if (settings_.focus_absolute >= 0) SetControl(V4L2_CID_FOCUS_ABSOLUTE, settings_.focus_absolute, "focus_absolute");
    if (settings_.exposure_us > 0) {
      SetControl(V4L2_CID_EXPOSURE_AUTO, V4L2_EXPOSURE_MANUAL, "manual exposure");
      // V4L2's absolute exposure is in units of 100 µs.
      SetControl(V4L2_CID_EXPOSURE_ABSOLUTE, std::max(1, settings_.exposure_us / 100), "exposure_us");
    }
    if (settings_.gain >= 0) SetControl(V4L2_CID_GAIN, settings_.gain, "gain");
  }

  Status StartStreaming() {
    v4l2_requestbuffers request{};
    request.count = static_cast<unsigned>(settings_.buffers);
    request.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    request.memory = V4L2_MEMORY_MMAP;
    if (Ioctl(fd_, VIDIOC_REQBUFS, &request) != 0 || request.count < 2) return Fail("cannot allocate capture buffers");
    for (unsigned i = 0; i < request.count; ++i) {
      v4l2_buffer buffer{};
      buffer.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
      buffer.memory = V4L2_MEMORY_MMAP;
      buffer.index = i;
      if (Ioctl(fd_, VIDIOC_QUERYBUF, &buffer) != 0) return Fail("cannot query capture buffers");
      void* start = v4l2_mmap(nullptr, buffer.length, PROT_READ | PROT_WRITE, MAP_SHARED, fd_, buffer.m.offset);
      if (start == MAP_FAILED) return Fail("cannot map capture buffers");
      buffers_.push_back({start, buffer.length});
      if (Ioctl(fd_, VIDIOC_QBUF, &buffer) != 0) return Fail("cannot queue capture buffers");
    }
    v4l2_buf_type type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    if (Ioctl(fd_, VIDIOC_STREAMON, &type) != 0) return Fail("cannot start streaming");
    return Status::Ok();
  }

  void Close() {
    if (fd_ < 0) return;
    v4l2_buf_type type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    Ioctl(fd_, VIDIOC_STREAMOFF, &type);
    for (const auto& b : buffers_) v4l2_munmap(b.start, b.length);
    buffers_.clear();
    v4l2_close(fd_);
    fd_ = -1;
  }

  std::string device_;
  CaptureSettings settings_;
  RecordingInfo info_;
  std::vector<std::string> warnings_;
  std::vector<MappedBuffer> buffers_;
  int fd_ = -1;
  int width_ = 0, height_ = 0, stride_ = 0;
  unsigned pixel_format_ = 0;
  FrameId next_index_ = 0;
};

}  // namespace

Result<std::unique_ptr<FrameSource>> OpenV4l2FrameSource(const std::string& device, const CaptureSettings& settings) {
  auto source = std::make_unique<V4l2FrameSource>(device, settings);
  if (Status s = source->Start(); !s) return s.error();
  return std::unique_ptr<FrameSource>(std::move(source));
}

#else

Result<std::unique_ptr<FrameSource>> OpenV4l2FrameSource(const std::string& device, const CaptureSettings&) {
  return MakeError("v4l2:" + device + ": this build has no V4L2 support (libv4l-dev was missing)");
}

#endif

}  // namespace tagsfm
