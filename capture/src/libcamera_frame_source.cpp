// libcamera:N — camera N of libcamera's camera manager (Debian's libcamera
// 0.0.3 API): one stream, the format chosen as for V4L2 and decoded by
// pixel_decode.h, requests recycled as they complete.
#include <sys/mman.h>

#include <chrono>
#include <condition_variable>
#include <deque>
#include <map>
#include <mutex>

#include "tagsfm/capture/frame_source.h"
#include "tagsfm/capture/pixel_decode.h"

#ifdef TAGSFM_HAVE_LIBCAMERA
#include <libcamera/libcamera.h>
#endif

namespace tagsfm {

#ifdef TAGSFM_HAVE_LIBCAMERA
namespace {

namespace lc = libcamera;

// libcamera names formats by DRM FourCC; the V4L2 names pixel_decode knows.
std::uint32_t V4l2FourCcOf(const lc::PixelFormat& format) {
  if (format == lc::formats::R8) return FourCc("GREY");
  if (format == lc::formats::YUYV) return FourCc("YUYV");
  if (format == lc::formats::UYVY) return FourCc("UYVY");
  if (format == lc::formats::MJPEG) return FourCc("MJPG");
  if (format == lc::formats::RGB888) return FourCc("BGR3");  // DRM RGB888 is B, G, R in memory
  if (format == lc::formats::BGR888) return FourCc("RGB3");
  return 0;
}

class LibcameraFrameSource : public FrameSource {
 public:
  LibcameraFrameSource(std::string uri, CaptureSettings settings) : uri_(std::move(uri)), settings_(std::move(settings)) {}
  ~LibcameraFrameSource() override { Close(); }

  Status Start(size_t index) {
    manager_ = std::make_unique<lc::CameraManager>();
    if (manager_->start() != 0) return Fail("libcamera's camera manager does not start");
    const auto cameras = manager_->cameras();
    if (index >= cameras.size()) {
      return Fail("no such camera (libcamera sees " + std::to_string(cameras.size()) + ")");
    }
    camera_ = cameras[index];
    if (camera_->acquire() != 0) return Fail("camera " + camera_->id() + " is in use");
    acquired_ = true;
    camera_->disconnected.connect(this, &LibcameraFrameSource::OnDisconnected);
    camera_->requestCompleted.connect(this, &LibcameraFrameSource::OnRequestCompleted);
    if (Status s = Configure(); !s) return s;
    if (Status s = AllocateAndMap(); !s) return s;
    lc::ControlList controls = Controls();
    if (camera_->start(&controls) != 0) return Fail("camera does not start");
    started_ = true;
    for (auto& request : requests_) {
      if (camera_->queueRequest(request.get()) != 0) return Fail("cannot queue capture requests");
    }
    return Status::Ok();
  }

  Result<std::optional<Frame>> Next() override {
    if (!started_) return MakeError(uri_ + ": camera is closed after an earlier error");
    for (;;) {
      lc::Request* request = WaitForRequest();
      if (request == nullptr) {
        const std::string why = disconnected_ ? "disconnected" : "no frame for 2.0 s";
        return Fail("camera lost " + (next_index_ == 0 ? std::string("before the first frame")
                                                        : "after frame " + std::to_string(next_index_ - 1)) + " (" + why + ")");
      }
      auto frame = TakeFrame(*request);
      request->reuse(lc::Request::ReuseBuffers);
      camera_->queueRequest(request);
      if (frame) return std::optional<Frame>(std::move(*frame));
      warnings_.push_back(uri_ + ": frame skipped (" + frame.error().message + ")");
    }
  }

  const RecordingInfo& info() const override { return info_; }
  std::string uri() const override { return uri_; }
  std::vector<std::string> TakeWarnings() override { return std::exchange(warnings_, {}); }

 private:
  Error Fail(const std::string& why) {
    Close();
    return MakeError(uri_ + ": " + why);
  }

  Status Configure() {
    config_ = camera_->generateConfiguration({lc::StreamRole::VideoRecording});
    if (!config_ || config_->size() != 1) return Fail("gives no video stream");
    lc::StreamConfiguration& stream = config_->at(0);
    std::uint32_t chosen = 0;
    for (const std::string& name : DecodablePixelFormats(settings_.colour)) {
      for (const lc::PixelFormat& f : stream.formats().pixelformats()) {
        if (chosen == 0 && V4l2FourCcOf(f) == FourCc(name) && (settings_.pixel_format.empty() || settings_.pixel_format == name)) {
          stream.pixelFormat = f;
          chosen = FourCc(name);
        }
      }
    }
    if (chosen == 0) return Fail("offers no pixel format tagsfm decodes" + (settings_.pixel_format.empty() ? "" : " as " + settings_.pixel_format));
    stream.size = lc::Size(static_cast<unsigned>(settings_.width), static_cast<unsigned>(settings_.height));
    stream.bufferCount = static_cast<unsigned>(settings_.buffers);
    if (config_->validate() == lc::CameraConfiguration::Invalid) return Fail("refuses the configuration " + stream.toString());
    if (camera_->configure(config_.get()) != 0) return Fail("refuses the configuration " + stream.toString());
    layout_ = {V4l2FourCcOf(stream.pixelFormat), static_cast<int>(stream.size.width), static_cast<int>(stream.size.height),
               static_cast<int>(stream.stride)};
    if (layout_.fourcc != chosen) return Fail("refuses the format " + FourCcName(chosen) + " (gives " + stream.toString() + ")");
    if (layout_.width != settings_.width || layout_.height != settings_.height) {
      warnings_.push_back(uri_ + ": asked for " + std::to_string(settings_.width) + "x" + std::to_string(settings_.height) +
                          ", the camera gives " + stream.size.toString());
    }
    return Status::Ok();
  }

  Status AllocateAndMap() {
    lc::Stream* stream = config_->at(0).stream();
    allocator_ = std::make_unique<lc::FrameBufferAllocator>(camera_);
    if (allocator_->allocate(stream) < 0) return Fail("cannot allocate capture buffers");
    for (const auto& buffer : allocator_->buffers(stream)) {
      const lc::FrameBuffer::Plane& plane = buffer->planes()[0];
      void* start = mmap(nullptr, plane.offset + plane.length, PROT_READ, MAP_SHARED, plane.fd.get(), 0);
      if (start == MAP_FAILED) return Fail("cannot map capture buffers");
      maps_[buffer.get()] = {static_cast<std::uint8_t*>(start), plane.offset + plane.length, plane.offset};
      std::unique_ptr<lc::Request> request = camera_->createRequest();
      if (!request || request->addBuffer(stream, buffer.get()) != 0) return Fail("cannot create capture requests");
      requests_.push_back(std::move(request));
    }
    return Status::Ok();
  }

  // The camera settings libcamera has controls for; the rest are said once.
  lc::ControlList Controls() {
    lc::ControlList controls;
    const lc::ControlInfoMap& known = camera_->controls();
    if (settings_.exposure_us > 0) {
      if (known.count(&lc::controls::ExposureTime)) {
        controls.set(lc::controls::AeEnable, false);
        controls.set(lc::controls::ExposureTime, settings_.exposure_us);
      } else {
        warnings_.push_back(uri_ + ": has no exposure time control: capture.exposure_us is ignored");
      }
    }
    if (known.count(&lc::controls::AfMode)) {
      controls.set(lc::controls::AfMode, settings_.autofocus ? lc::controls::AfModeContinuous : lc::controls::AfModeManual);
    } else if (settings_.autofocus) {
      warnings_.push_back(uri_ + ": has no autofocus control: capture.autofocus is ignored");
    }
    if (settings_.gain >= 0 || settings_.brightness || settings_.focus_absolute >= 0) {
      warnings_.push_back(uri_ + ": capture.gain, capture.brightness and capture.focus_absolute are V4L2 units; "
                                 "libcamera sources ignore them");
    }
    return controls;
  }

  lc::Request* WaitForRequest() {
    std::unique_lock<std::mutex> lock(mutex_);
    const bool ready = completed_cv_.wait_for(lock, std::chrono::seconds(2),
                                              [&] { return !completed_.empty() || disconnected_; });
    if (!ready || completed_.empty()) return nullptr;
    lc::Request* request = completed_.front();
    completed_.pop_front();
    return request;
  }

  Result<Frame> TakeFrame(lc::Request& request) {
    if (request.status() != lc::Request::RequestComplete) return MakeError("request cancelled");
    lc::FrameBuffer* buffer = request.buffers().begin()->second;
    const lc::FrameMetadata& meta = buffer->metadata();
    if (meta.status != lc::FrameMetadata::FrameSuccess) return MakeError("the camera marked the frame as corrupt");
    const Mapped& map = maps_.at(buffer);
    auto pixels = DecodePixels(layout_, map.start + map.offset, meta.planes()[0].bytesused, settings_.colour);
    if (!pixels) return pixels.error();
    Frame frame;
    frame.index = next_index_++;
    frame.timestamp_ns = static_cast<std::int64_t>(meta.timestamp);
    frame.image = std::move(pixels->image);
    frame.gray = std::move(pixels->gray);
    frame.source = uri_;
    return frame;
  }

  // libcamera's own thread.
  void OnRequestCompleted(lc::Request* request) {
    if (request->status() == lc::Request::RequestCancelled) return;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      completed_.push_back(request);
    }
    completed_cv_.notify_one();
  }
  void OnDisconnected() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      disconnected_ = true;
    }
    completed_cv_.notify_one();
  }

  void Close() {
    if (started_) camera_->stop();
    started_ = false;
    if (camera_) {
      camera_->requestCompleted.disconnect(this);
      camera_->disconnected.disconnect(this);
    }
    requests_.clear();
    completed_.clear();
    for (const auto& [buffer, map] : maps_) munmap(map.start, map.length);
    maps_.clear();
    allocator_.reset();
    if (acquired_) camera_->release();
    acquired_ = false;
    config_.reset();
    camera_.reset();
    if (manager_) manager_->stop();
    manager_.reset();
  }

  struct Mapped {
    std::uint8_t* start = nullptr;
    size_t length = 0;
    size_t offset = 0;
  };

  std::string uri_;
  CaptureSettings settings_;
  RecordingInfo info_;
  std::vector<std::string> warnings_;
  std::unique_ptr<lc::CameraManager> manager_;
  std::shared_ptr<lc::Camera> camera_;
  std::unique_ptr<lc::CameraConfiguration> config_;
  std::unique_ptr<lc::FrameBufferAllocator> allocator_;
  std::vector<std::unique_ptr<lc::Request>> requests_;
  std::map<const lc::FrameBuffer*, Mapped> maps_;
  PixelLayout layout_;
  std::mutex mutex_;
  std::condition_variable completed_cv_;
  std::deque<lc::Request*> completed_;
  bool disconnected_ = false;
  bool acquired_ = false;
  bool started_ = false;
  FrameId next_index_ = 0;
};

}  // namespace

Result<std::unique_ptr<FrameSource>> OpenLibcameraFrameSource(const std::string& spec, const CaptureSettings& settings) {
  const std::string uri = "libcamera:" + spec;
  size_t index = 0;
  try {
    size_t used = 0;
    index = std::stoul(spec, &used);
    if (used != spec.size()) throw std::invalid_argument(spec);
  } catch (const std::exception&) {
    return MakeError("camera source '" + uri + "': expected libcamera:N, N the camera's number (0 for the first)");
  }
  auto source = std::make_unique<LibcameraFrameSource>(uri, settings);
  if (Status s = source->Start(index); !s) return s.error();
  return std::unique_ptr<FrameSource>(std::move(source));
}

#else

Result<std::unique_ptr<FrameSource>> OpenLibcameraFrameSource(const std::string& spec, const CaptureSettings&) {
  return MakeError("libcamera:" + spec + ": this build has no libcamera support (libcamera-dev was missing)");
}

#endif

}  // namespace tagsfm
