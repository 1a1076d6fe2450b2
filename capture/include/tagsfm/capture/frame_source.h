#pragma once
// Where frames come from, named by a URI:
//   file:REC            a recording played at its own timestamps
//   file:REC?rate=max   a recording as fast as it can be read
//   v4l2:/dev/videoN    a V4L2 camera
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "tagsfm/capture/capture_settings.h"
#include "tagsfm/capture/frame.h"
#include "tagsfm/capture/recording.h"

namespace tagsfm {

class FrameSource {
 public:
  virtual ~FrameSource() = default;
  // The next frame; nullopt at the end of a recording. A camera that
  // vanishes is an error naming it, after which Next() keeps failing.
  virtual Result<std::optional<Frame>> Next() = 0;
  // The camera and targets when the source knows them (a recording does).
  virtual const RecordingInfo& info() const = 0;
  virtual std::string uri() const = 0;
  // Things the source could not do as asked but can work without (e.g. a
  // camera control the driver lacks); returned once, then cleared.
  virtual std::vector<std::string> TakeWarnings() { return {}; }
};

Result<std::unique_ptr<FrameSource>> OpenFrameSource(const std::string& uri);
// A camera with the given settings (settings.source names it); a recording
// URI ignores the camera settings.
Result<std::unique_ptr<FrameSource>> OpenFrameSource(const CaptureSettings& settings);

}  // namespace tagsfm
