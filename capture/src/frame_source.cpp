#include "tagsfm/capture/frame_source.h"

namespace tagsfm {

Result<std::unique_ptr<FrameSource>> OpenFileFrameSource(const std::string& uri, const std::string& spec);

Result<std::unique_ptr<FrameSource>> OpenFrameSource(const std::string& uri) {
  const size_t colon = uri.find(':');
  if (colon == std::string::npos) {
    return MakeError("camera source '" + uri + "': expected a URI such as file:REC, v4l2:/dev/video0 or libcamera:0");
  }
  const std::string scheme = uri.substr(0, colon);
  const std::string spec = uri.substr(colon + 1);
  if (scheme == "file") return OpenFileFrameSource(uri, spec);
  return MakeError("camera source '" + uri + "': scheme '" + scheme + "' is not supported yet (supported: file)");
}

}  // namespace tagsfm
