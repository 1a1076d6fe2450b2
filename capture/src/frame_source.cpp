#include "tagsfm/capture/frame_source.h"

namespace tagsfm {

Result<std::unique_ptr<FrameSource>> OpenFileFrameSource(const std::string& uri, const std::string& spec);
Result<std::unique_ptr<FrameSource>> OpenV4l2FrameSource(const std::string& path, const CaptureSettings& settings);
Result<std::unique_ptr<FrameSource>> OpenLibcameraFrameSource(const std::string& spec, const CaptureSettings& settings);

Result<std::unique_ptr<FrameSource>> OpenFrameSource(const CaptureSettings& settings) {
  if (Status s = settings.Check(); !s) return s.error();
  const std::string& uri = settings.source;
  const size_t colon = uri.find(':');
  const std::string scheme = uri.substr(0, colon);
  const std::string spec = uri.substr(colon + 1);
  if (scheme == "file") return OpenFileFrameSource(uri, spec);
  if (scheme == "v4l2") return OpenV4l2FrameSource(spec, settings);
  if (scheme == "libcamera") return OpenLibcameraFrameSource(spec, settings);
  return MakeError("camera source '" + uri + "': unknown scheme '" + scheme + "' (known: file, v4l2, libcamera)");
}

Result<std::unique_ptr<FrameSource>> OpenFrameSource(const std::string& uri) {
  if (uri.find(':') == std::string::npos) {
    return MakeError("camera source '" + uri + "': expected a URI such as file:REC, v4l2:/dev/video0 or libcamera:0");
  }
  CaptureSettings settings;
  settings.source = uri;
  return OpenFrameSource(settings);
}

}  // namespace tagsfm
