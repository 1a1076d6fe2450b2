#pragma once
// A scripted V4L2 camera for the streaming tests: it keeps buffers the way
// the kernel's videobuf2 does (a buffer is dequeued only once queued, twice
// queued is EINVAL), fills them with the frames a test asks for, and plays a
// script of what happens at each wait: a frame, EAGAIN, a timeout, a corrupt
// buffer, an error such as ENODEV (the camera unplugged).
#include <linux/videodev2.h>

#include <cerrno>
#include <cstring>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "tagsfm/capture/v4l2_device.h"

namespace tagsfm::testing {

struct FakeStep {
  enum Kind { kFrame, kEagain, kTimeout, kCorrupt, kError } kind = kFrame;
  int error = 0;              // kError: what DQBUF fails with
  std::uint32_t skipped = 0;  // kFrame: frames the "driver" dropped before this one
};

struct FakeControl {
  int minimum = 0, maximum = 255, value = 0;
  int set_error = 0;   // S_CTRL fails with this
  int keeps = -1;      // >= 0: S_CTRL succeeds but the camera keeps this value
};

// Everything a test sets up or looks at; shared with the device the source owns.
struct FakeCamera {
  // What the camera offers.
  std::vector<std::uint32_t> formats = {V4L2_PIX_FMT_GREY};
  int width = 64, height = 48;
  int row_padding = 0;         // bytes after each row (bytesperline > width * bpp)
  int s_fmt_error = 0;         // S_FMT fails with this
  std::map<unsigned, FakeControl> controls;
  // The bytes of frame n (n counts the frames the camera delivered).
  std::function<std::vector<std::uint8_t>(int n)> frame_bytes;
  std::deque<FakeStep> script;  // empty: nothing more comes (poll times out)
  int opens_to_fail = 0;        // after an error: opens that fail (ENOENT) before it is back
  bool gone_for_good = false;

  // What happened.
  int opens = 0, closes = 0, stream_ons = 0, stream_offs = 0, mapped = 0;
  std::uint32_t pixel_format = 0;
  std::vector<unsigned> dequeued;  // buffer indices, in order
  std::vector<std::string> violations;
  bool gone = false;

  // Internal buffer state.
  std::vector<std::vector<std::uint8_t>> buffers;
  std::deque<unsigned> queued;
  int delivered = 0;
  std::uint32_t sequence = 0;
  bool streaming = false;
};

class FakeV4l2Device : public V4l2Device {
 public:
  explicit FakeV4l2Device(std::shared_ptr<FakeCamera> camera) : c_(std::move(camera)) {}

  int Open(const std::string&) override {
    if (c_->gone && (c_->gone_for_good || c_->opens_to_fail-- > 0)) return ENOENT;
    if (c_->gone) {  // back, as a new device: nothing streams, nothing is queued
      c_->gone = false;
      c_->streaming = false;
      c_->queued.clear();
    }
    ++c_->opens;
    return 0;
  }
  void Close() override { ++c_->closes; }
  void* Map(size_t length, std::int64_t offset) override {
    const size_t i = static_cast<size_t>(offset / kOffsetStep);
    if (i >= c_->buffers.size() || length != c_->buffers[i].size()) return nullptr;
    ++c_->mapped;
    return c_->buffers[i].data();
  }
  void Unmap(void*, size_t) override { --c_->mapped; }

  int Poll(int) override {
    if (c_->gone) return 0;  // the kernel wakes a waiter on a vanished device
    if (c_->script.empty()) return ETIMEDOUT;
    const FakeStep& step = c_->script.front();
    if (step.kind == FakeStep::kTimeout) {
      c_->script.pop_front();
      return ETIMEDOUT;
    }
    if ((step.kind == FakeStep::kFrame || step.kind == FakeStep::kCorrupt) && c_->queued.empty()) return ETIMEDOUT;
    return 0;
  }

  int Ioctl(unsigned long request, void* arg) override {
    if (c_->gone) return ENODEV;
    switch (request) {
      case VIDIOC_QUERYCAP: {
        auto* cap = static_cast<v4l2_capability*>(arg);
        cap->capabilities = V4L2_CAP_VIDEO_CAPTURE | V4L2_CAP_STREAMING;
        return 0;
      }
      case VIDIOC_ENUM_FMT: {
        auto* desc = static_cast<v4l2_fmtdesc*>(arg);
        if (desc->index >= c_->formats.size()) return EINVAL;
        desc->pixelformat = c_->formats[desc->index];
        return 0;
      }
      case VIDIOC_S_FMT: return SetFormat(static_cast<v4l2_format*>(arg));
      case VIDIOC_S_PARM: return 0;  // keeps the asked rate
      case VIDIOC_QUERYCTRL: return QueryControl(static_cast<v4l2_queryctrl*>(arg));
      case VIDIOC_S_CTRL: return SetControl(static_cast<v4l2_control*>(arg));
      case VIDIOC_G_CTRL: {
        auto* control = static_cast<v4l2_control*>(arg);
        if (!c_->controls.count(control->id)) return EINVAL;
        control->value = c_->controls[control->id].value;
        return 0;
      }
      case VIDIOC_REQBUFS: return RequestBuffers(static_cast<v4l2_requestbuffers*>(arg));
      case VIDIOC_QUERYBUF: {
        auto* buffer = static_cast<v4l2_buffer*>(arg);
        if (buffer->index >= c_->buffers.size()) return EINVAL;
        buffer->length = static_cast<unsigned>(c_->buffers[buffer->index].size());
        buffer->m.offset = buffer->index * kOffsetStep;
        return 0;
      }
      case VIDIOC_QBUF: {
        // As videobuf2 does, QBUF writes the struct back with what a queued
        // capture buffer has: no timestamp, no data, no sequence.
        auto* buffer = static_cast<v4l2_buffer*>(arg);
        const int error = Queue(buffer->index);
        buffer->timestamp = {};
        buffer->bytesused = 0;
        buffer->sequence = 0;
        return error;
      }
      case VIDIOC_DQBUF: return Dequeue(static_cast<v4l2_buffer*>(arg));
      case VIDIOC_STREAMON: ++c_->stream_ons; c_->streaming = true; return 0;
      case VIDIOC_STREAMOFF: ++c_->stream_offs; c_->streaming = false; c_->queued.clear(); return 0;
      default: return ENOTTY;
    }
  }

 private:
  static constexpr unsigned kOffsetStep = 1u << 24;

  int BytesPerPixel() const {
    return c_->pixel_format == V4L2_PIX_FMT_GREY ? 1 : (c_->pixel_format == V4L2_PIX_FMT_BGR24 ? 3 : 2);
  }

  int SetFormat(v4l2_format* format) {
    if (c_->s_fmt_error) return c_->s_fmt_error;
    auto& pix = format->fmt.pix;
    bool offered = false;
    for (auto f : c_->formats) offered |= f == pix.pixelformat;
    if (!offered) pix.pixelformat = c_->formats.front();  // drivers substitute what they have
    c_->pixel_format = pix.pixelformat;
    pix.width = static_cast<unsigned>(c_->width);
    pix.height = static_cast<unsigned>(c_->height);
    const bool compressed = pix.pixelformat == V4L2_PIX_FMT_MJPEG;
    pix.bytesperline = compressed ? 0 : static_cast<unsigned>(c_->width * BytesPerPixel() + c_->row_padding);
    pix.sizeimage = compressed ? static_cast<unsigned>(c_->width * c_->height * 2) : pix.bytesperline * pix.height;
    pix.field = V4L2_FIELD_NONE;
    return 0;
  }

  int QueryControl(v4l2_queryctrl* query) {
    auto it = c_->controls.find(query->id);
    if (it == c_->controls.end()) return EINVAL;
    query->minimum = it->second.minimum;
    query->maximum = it->second.maximum;
    return 0;
  }

  int SetControl(v4l2_control* control) {
    auto it = c_->controls.find(control->id);
    if (it == c_->controls.end()) return EINVAL;
    if (it->second.set_error) return it->second.set_error;
    it->second.value = it->second.keeps >= 0 ? it->second.keeps : control->value;
    return 0;
  }

  int RequestBuffers(v4l2_requestbuffers* request) {
    if (c_->streaming) return EBUSY;
    if (c_->mapped > 0 && request->count > 0) return EBUSY;  // the kernel refuses while mapped
    const size_t size = static_cast<size_t>(c_->width) * static_cast<size_t>(c_->height) * 3 +
                        static_cast<size_t>(c_->row_padding * c_->height);
    c_->buffers.assign(request->count, std::vector<std::uint8_t>(size, 0));
    c_->queued.clear();
    return 0;
  }

  int Queue(unsigned index) {
    if (index >= c_->buffers.size()) return EINVAL;
    for (unsigned q : c_->queued) {
      if (q == index) {
        c_->violations.push_back("buffer " + std::to_string(index) + " queued twice");
        return EINVAL;
      }
    }
    c_->queued.push_back(index);
    return 0;
  }

  int Dequeue(v4l2_buffer* buffer) {
    if (!c_->streaming) c_->violations.push_back("DQBUF while not streaming");
    if (c_->script.empty()) return EAGAIN;
    const FakeStep step = c_->script.front();
    if (step.kind == FakeStep::kEagain || step.kind == FakeStep::kTimeout) {
      if (step.kind == FakeStep::kEagain) c_->script.pop_front();
      return EAGAIN;
    }
    if (step.kind == FakeStep::kError) {
      c_->script.pop_front();
      c_->gone = true;
      return step.error;
    }
    if (c_->queued.empty()) return EAGAIN;
    c_->script.pop_front();
    const unsigned index = c_->queued.front();
    c_->queued.pop_front();
    c_->dequeued.push_back(index);
    c_->sequence += step.skipped;
    buffer->index = index;
    buffer->sequence = c_->sequence++;
    buffer->flags = step.kind == FakeStep::kCorrupt ? V4L2_BUF_FLAG_ERROR : 0;
    const std::int64_t t_us = 1'000'000 + 33'333LL * buffer->sequence;
    buffer->timestamp.tv_sec = t_us / 1'000'000;
    buffer->timestamp.tv_usec = t_us % 1'000'000;
    std::vector<std::uint8_t> bytes = c_->frame_bytes ? c_->frame_bytes(c_->delivered) : std::vector<std::uint8_t>();
    ++c_->delivered;
    auto& target = c_->buffers[index];
    if (!bytes.empty()) std::memcpy(target.data(), bytes.data(), std::min(bytes.size(), target.size()));
    buffer->bytesused = static_cast<unsigned>(std::min(bytes.size(), target.size()));
    return 0;
  }

  std::shared_ptr<FakeCamera> c_;
};

}  // namespace tagsfm::testing
