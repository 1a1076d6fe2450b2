#pragma once
// The camera controls a CaptureSettings asks for (focus, exposure, gain,
// brightness), applied to an open V4L2 device and read back.
#include <set>
#include <string>
#include <vector>

#include "tagsfm/capture/capture_settings.h"
#include "tagsfm/capture/v4l2_device.h"

namespace tagsfm {

// Applies the controls and appends a one-line warning, naming `uri` and the
// setting, for each that the camera lacks, refuses or changes. A setting
// already in `warned` is not warned about again (controls are applied anew
// after a reconnect); each warned setting is added to it.
void ApplyV4l2Controls(V4l2Device& device, const CaptureSettings& settings, const std::string& uri,
                       std::set<std::string>& warned, std::vector<std::string>& warnings);

}  // namespace tagsfm
