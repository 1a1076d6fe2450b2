// v4l2:/dev/videoN — a V4L2 camera: format negotiation, controls, mmap
// streaming, and what happens when the camera stops delivering.
#include <linux/videodev2.h>

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <chrono>
#include <cstring>
#include <set>
#include <thread>

#include "tagsfm/capture/pixel_decode.h"
#include "tagsfm/capture/v4l2_device.h"
#include "v4l2_controls.h"

namespace tagsfm {
namespace {

using Clock = std::chrono::steady_clock;

std::string ErrnoText(int error) { return std::strerror(error); }

std::string Seconds(double s) {
  char text[32];
  std::snprintf(text, sizeof text, "%.1f s", s);
  return text;
}

class V4l2FrameSource : public FrameSource {
 public:
  V4l2FrameSource(std::string path, std::unique_ptr<V4l2Device> device, CaptureSettings settings)
      : path_(std::move(path)), device_(std::move(device)), settings_(std::move(settings)) {}
  ~V4l2FrameSource() override { Close(); }

  // Opens the device and starts streaming; also used to resume after the
  // camera came back.
  Status Start() {
    if (const int error = device_->Open(path_); error != 0) return Fail("cannot open (" + ErrnoText(error) + ")");
    open_ = true;
    v4l2_capability cap{};
    if (device_->Ioctl(VIDIOC_QUERYCAP, &cap) != 0) return Fail("is not a V4L2 device");
    const unsigned caps = (cap.capabilities & V4L2_CAP_DEVICE_CAPS) ? cap.device_caps : cap.capabilities;
    if (!(caps & V4L2_CAP_VIDEO_CAPTURE) || !(caps & V4L2_CAP_STREAMING)) {
      return Fail("is not a streaming video capture device");
    }
    if (Status s = NegotiateFormat(); !s) return s;
    SetFrameRate();
    ApplyV4l2Controls(*device_, settings_, uri(), warned_, warnings_);
    return StartStreaming();
  }

  Result<std::optional<Frame>> Next() override {
    if (failed_) return MakeError(uri() + ": camera is closed after an earlier error");
    for (;;) {
      v4l2_buffer buffer{};
      const int error = Dequeue(buffer);
      if (error != 0) {
        if (Status back = AwaitReturn(error); !back) return back.error();
        continue;
      }
      auto frame = DecodeAndRequeue(buffer);
      if (!frame) return frame.error();
      if (frame->has_value()) return frame;
    }
  }

  const RecordingInfo& info() const override { return info_; }
  std::string uri() const override { return "v4l2:" + path_; }
  std::vector<std::string> TakeWarnings() override {
    if (dropped_ > reported_dropped_) {
      warnings_.push_back(uri() + ": the driver dropped " + std::to_string(dropped_) +
                          " frames so far (gaps in its frame sequence): the disk or the CPU may be too slow");
      reported_dropped_ = dropped_;
    }
    if (corrupt_ > reported_corrupt_) {
      warnings_.push_back(uri() + ": " + std::to_string(corrupt_) + " corrupt frames skipped so far (" + last_corrupt_ + ")");
      reported_corrupt_ = corrupt_;
    }
    return std::exchange(warnings_, {});
  }

 private:
  struct MappedBuffer {
    void* start = nullptr;
    size_t length = 0;
  };

  Error Fail(const std::string& why) {
    Close();
    failed_ = true;
    return MakeError(uri() + ": " + why);
  }

  // Warnings about the negotiation are said once, not again after a reconnect.
  void WarnOnce(const std::string& key, const std::string& message) {
    if (warned_.insert(key).second) warnings_.push_back(uri() + ": " + message);
  }

  std::string AfterFrameText() const {
    return next_index_ == 0 ? "before the first frame" : "after frame " + std::to_string(next_index_ - 1);
  }

  // A camera that delivers nothing for 2 s (or 10 frame times) is gone.
  double FrameTimeoutS() const { return std::max(2.0, 10.0 / settings_.fps); }

  std::vector<std::uint32_t> OfferedFormats() {
    std::vector<std::uint32_t> offered;
    for (unsigned i = 0; i < 64; ++i) {
      v4l2_fmtdesc desc{};
      desc.index = i;
      desc.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
      if (device_->Ioctl(VIDIOC_ENUM_FMT, &desc) != 0) break;
      offered.push_back(desc.pixelformat);
    }
    return offered;
  }

  Status NegotiateFormat() {
    auto chosen = ChoosePixelFormat(OfferedFormats(), settings_.pixel_format, settings_.colour);
    if (!chosen) return Fail(chosen.error().message);
    v4l2_format format{};
    format.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    format.fmt.pix.width = static_cast<unsigned>(settings_.width);
    format.fmt.pix.height = static_cast<unsigned>(settings_.height);
    format.fmt.pix.pixelformat = *chosen;
    format.fmt.pix.field = V4L2_FIELD_NONE;
    const std::string asked = FourCcName(*chosen) + " " + std::to_string(settings_.width) + "x" + std::to_string(settings_.height);
    if (const int error = device_->Ioctl(VIDIOC_S_FMT, &format); error != 0) {
      return Fail("refuses the format " + asked + " (" + ErrnoText(error) + ")");
    }
    layout_ = {format.fmt.pix.pixelformat, static_cast<int>(format.fmt.pix.width), static_cast<int>(format.fmt.pix.height),
               static_cast<int>(format.fmt.pix.bytesperline)};
    if (!CanDecodePixelFormat(layout_.fourcc) || (!settings_.pixel_format.empty() && layout_.fourcc != *chosen)) {
      return Fail("refuses the format " + asked + " (it offers " + FourCcName(layout_.fourcc) + " instead)");
    }
    if (format.fmt.pix.field != V4L2_FIELD_NONE && format.fmt.pix.field != V4L2_FIELD_ANY) {
      WarnOnce("field", "frames are interlaced (field order " + std::to_string(format.fmt.pix.field) +
                            "): expect combing on moving edges");
    }
    if (layout_.width != settings_.width || layout_.height != settings_.height) {
      WarnOnce("size", "asked for " + std::to_string(settings_.width) + "x" + std::to_string(settings_.height) +
                           " (capture.width, capture.height), the camera gives " + std::to_string(layout_.width) + "x" +
                           std::to_string(layout_.height));
    }
    return Status::Ok();
  }

  void SetFrameRate() {
    v4l2_streamparm parm{};
    parm.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    parm.parm.capture.timeperframe.numerator = 1000;
    parm.parm.capture.timeperframe.denominator = static_cast<unsigned>(settings_.fps * 1000);
    if (device_->Ioctl(VIDIOC_S_PARM, &parm) != 0) {
      WarnOnce("fps", "cannot set the frame rate (capture.fps)");
      return;
    }
    const auto& tpf = parm.parm.capture.timeperframe;
    const double got = tpf.numerator > 0 ? static_cast<double>(tpf.denominator) / tpf.numerator : 0.0;
    if (got > 0 && std::abs(got - settings_.fps) > 0.01 * settings_.fps) {
      char text[96];
      std::snprintf(text, sizeof text, "asked for %.2f fps (capture.fps), the camera gives %.2f", settings_.fps, got);
      WarnOnce("fps", text);
    }
  }

  Status StartStreaming() {
    v4l2_requestbuffers request{};
    request.count = static_cast<unsigned>(settings_.buffers);
    request.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    request.memory = V4L2_MEMORY_MMAP;
    if (const int error = device_->Ioctl(VIDIOC_REQBUFS, &request); error != 0 || request.count < 2) {
      return Fail("cannot allocate capture buffers (" + (error ? ErrnoText(error) : "fewer than 2 given") + ")");
    }
    for (unsigned i = 0; i < request.count; ++i) {
      v4l2_buffer buffer{};
      buffer.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
      buffer.memory = V4L2_MEMORY_MMAP;
      buffer.index = i;
      if (device_->Ioctl(VIDIOC_QUERYBUF, &buffer) != 0) return Fail("cannot query capture buffers");
      void* start = device_->Map(buffer.length, buffer.m.offset);
      if (start == nullptr) return Fail("cannot map capture buffers");
      buffers_.push_back({start, buffer.length});
      if (device_->Ioctl(VIDIOC_QBUF, &buffer) != 0) return Fail("cannot queue capture buffers");
    }
    v4l2_buf_type type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    if (const int error = device_->Ioctl(VIDIOC_STREAMON, &type); error != 0) {
      return Fail("cannot start streaming (" + ErrnoText(error) + ")");
    }
    streaming_ = true;
    sequence_known_ = false;
    return Status::Ok();
  }

  // 0 and a filled buffer, or the errno that ends the stream (ETIMEDOUT when
  // nothing came in time). EAGAIN (woken with nothing to dequeue) waits on.
  int Dequeue(v4l2_buffer& buffer) {
    const auto deadline = Clock::now() + std::chrono::duration<double>(FrameTimeoutS());
    for (;;) {
      const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now()).count();
      if (left <= 0) return ETIMEDOUT;
      const int polled = device_->Poll(static_cast<int>(left));
      if (polled != 0 && polled != EINTR) return polled;
      buffer = {};
      buffer.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
      buffer.memory = V4L2_MEMORY_MMAP;
      const int error = device_->Ioctl(VIDIOC_DQBUF, &buffer);
      if (error != EAGAIN) return error;
    }
  }

  // The frame in `buffer`, or nullopt for a frame skipped as corrupt; the
  // buffer goes back to the driver either way.
  Result<std::optional<Frame>> DecodeAndRequeue(v4l2_buffer& buffer) {
    if (buffer.index >= buffers_.size()) return Fail("the driver returned an unknown buffer " + std::to_string(buffer.index));
    if (sequence_known_ && buffer.sequence > last_sequence_ + 1) dropped_ += buffer.sequence - last_sequence_ - 1;
    last_sequence_ = buffer.sequence;
    sequence_known_ = true;
    Result<DecodedPixels> pixels = MakeError("the driver marked the buffer as corrupt");
    if (!(buffer.flags & V4L2_BUF_FLAG_ERROR)) {
      const size_t used = buffer.bytesused > 0 ? buffer.bytesused : buffers_[buffer.index].length;
      pixels = DecodePixels(layout_, static_cast<const std::uint8_t*>(buffers_[buffer.index].start), used, settings_.colour);
    }
    // QBUF writes the buffer struct back (the kernel clears its timestamp):
    // take what the frame needs from it first.
    const std::int64_t timestamp_ns = static_cast<std::int64_t>(buffer.timestamp.tv_sec) * 1'000'000'000 +
                                      static_cast<std::int64_t>(buffer.timestamp.tv_usec) * 1000;
    if (const int error = device_->Ioctl(VIDIOC_QBUF, &buffer); error != 0) {
      if (Status back = AwaitReturn(error); !back) return back.error();
    }
    if (!pixels) {
      ++corrupt_;
      last_corrupt_ = "frame after " + std::to_string(next_index_) + ": " + pixels.error().message;
      return std::optional<Frame>();
    }
    Frame frame;
    frame.index = next_index_++;
    frame.timestamp_ns = timestamp_ns;
    frame.image = std::move(pixels->image);
    frame.gray = std::move(pixels->gray);
    frame.source = uri();
    return std::optional<Frame>(std::move(frame));
  }

  // The stream ended with `error`: fails at once, or (capture.reconnect_wait_s
  // > 0) reopens the camera until it is back or the wait is over.
  Status AwaitReturn(int error) {
    const std::string why = error == ETIMEDOUT ? "no frame for " + Seconds(FrameTimeoutS()) : ErrnoText(error);
    const std::string lost = "camera lost " + AfterFrameText() + " (" + why + ")";
    Close();
    if (!(settings_.reconnect_wait_s > 0)) return Fail(lost);
    const auto start = Clock::now();
    const auto deadline = start + std::chrono::duration<double>(settings_.reconnect_wait_s);
    while (Clock::now() < deadline) {
      std::this_thread::sleep_for(std::chrono::milliseconds(200));
      if (Start()) {
        failed_ = false;
        const double waited = std::chrono::duration<double>(Clock::now() - start).count();
        warnings_.push_back(uri() + ": " + lost + "; it came back after " + Seconds(waited) + ", capture goes on");
        return Status::Ok();
      }
    }
    return Fail(lost + "; it did not come back within " + Seconds(settings_.reconnect_wait_s) + " (capture.reconnect_wait_s)");
  }

  void Close() {
    if (streaming_) {
      v4l2_buf_type type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
      device_->Ioctl(VIDIOC_STREAMOFF, &type);
      streaming_ = false;
    }
    for (const auto& b : buffers_) device_->Unmap(b.start, b.length);
    buffers_.clear();
    if (open_) device_->Close();
    open_ = false;
  }

  std::string path_;
  std::unique_ptr<V4l2Device> device_;
  CaptureSettings settings_;
  RecordingInfo info_;
  PixelLayout layout_;
  std::vector<MappedBuffer> buffers_;
  std::vector<std::string> warnings_;
  std::set<std::string> warned_;  // settings already warned about, so a reconnect does not repeat them
  bool open_ = false;
  bool streaming_ = false;
  bool failed_ = false;
  FrameId next_index_ = 0;
  std::uint32_t last_sequence_ = 0;
  bool sequence_known_ = false;
  size_t dropped_ = 0, reported_dropped_ = 0;
  size_t corrupt_ = 0, reported_corrupt_ = 0;
  std::string last_corrupt_;
};

}  // namespace

Result<std::unique_ptr<FrameSource>> OpenV4l2FrameSource(const std::string& path, std::unique_ptr<V4l2Device> device,
                                                          const CaptureSettings& settings) {
  auto source = std::make_unique<V4l2FrameSource>(path, std::move(device), settings);
  if (Status s = source->Start(); !s) return s.error();
  return std::unique_ptr<FrameSource>(std::move(source));
}

Result<std::unique_ptr<FrameSource>> OpenV4l2FrameSource(const std::string& path, const CaptureSettings& settings) {
  return OpenV4l2FrameSource(path, MakeSystemV4l2Device(), settings);
}

}  // namespace tagsfm
