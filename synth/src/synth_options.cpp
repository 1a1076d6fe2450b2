#include "tagsfm/synth/synth_options.h"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "tagsfm/capture/recording.h"

namespace tagsfm::synth {
namespace {

template <class T>
Error FieldError(const std::string& flag, const std::string& rule, const T& got) {
  std::ostringstream out;
  out << "--" << flag << " " << rule << " (got " << got << ")";
  return MakeError(out.str());
}

bool Finite(double v) { return std::isfinite(v); }

}  // namespace

Status SynthOptions::Check() const {
  if (scene != "box" && scene != "wall" && scene != "room") return FieldError("scene", "must be 'box', 'wall' or 'room'", scene);
  if (path != "orbit" && path != "photos") return FieldError("path", "must be 'orbit' or 'photos'", path);
  if (frames < 1 || frames > 100000) return FieldError("frames", "must be in 1..100000", frames);
  if (width < 16 || width > 16384) return FieldError("width", "must be in 16..16384", width);
  if (height < 16 || height > 16384) return FieldError("height", "must be in 16..16384", height);
  if (fx < 0 || !Finite(fx)) return FieldError("fx", "must be > 0 (or 0 for the default)", fx);
  if (fy < 0 || !Finite(fy)) return FieldError("fy", "must be > 0 (or 0 for the default)", fy);
  if (!distortion.empty() && distortion.size() != 4 && distortion.size() != 5) {
    return FieldError("distortion", "takes 4 or 5 values k1,k2,p1,p2[,k3]", distortion.size());
  }
  for (double d : distortion) {
    if (!Finite(d) || std::abs(d) > 10) return FieldError("distortion", "values must be finite and within +-10", d);
  }
  if (!(noise >= 0) || noise > 100) return FieldError("noise", "must be in 0..100 grey levels", noise);
  if (!(blur >= 0) || blur > 50) return FieldError("blur", "must be in 0..50 pixels", blur);
  if (!(brightness > 0) || brightness > 100) return FieldError("brightness", "must be in (0, 100]", brightness);
  const auto& families = KnownTagFamilies();
  if (std::find(families.begin(), families.end(), family) == families.end()) {
    return FieldError("family", "is not a libapriltag family", family);
  }
  if (!(tag_size >= 0.01) || tag_size > 0.2) return FieldError("tag-size", "must be in 0.01..0.2 m", tag_size);
  if (!(tag_margin >= 1.0) || tag_margin > 10) return FieldError("tag-margin", "must be in 1..10 modules", tag_margin);
  if (!(print_scale >= 0.9) || print_scale > 1.1) return FieldError("print-scale", "must be in 0.9..1.1", print_scale);
  if (!(scale_bar_sigma_m > 0) || scale_bar_sigma_m > 0.01) {
    return FieldError("scale-bar-sigma", "must be in (0, 0.01] m", scale_bar_sigma_m);
  }
  for (const auto& [a, b] : scale_bars) {
    if (a < 0 || b < 0 || a == b) return FieldError("scale-bar", "takes two different tag ids A,B", a);
  }
  if (!(min_distance >= 0.5)) return FieldError("distance", "minimum must be >= 0.5 m", min_distance);
  if (!(max_distance >= min_distance) || max_distance > 50) {
    return FieldError("distance", "maximum must be in [minimum, 50] m", max_distance);
  }
  if (!(max_azimuth_deg >= 0) || max_azimuth_deg > 85) return FieldError("azimuth", "must be in 0..85 degrees", max_azimuth_deg);
  if (samples < 1 || samples > 16) return FieldError("samples", "must be in 1..16", samples);
  if (threads < 1 || threads > 64) return FieldError("threads", "must be in 1..64", threads);
  if (Status s = Camera().Check(); !s) return s;
  return Status::Ok();
}

CameraModel SynthOptions::Camera() const {
  CameraModel camera;
  camera.width = width;
  camera.height = height;
  camera.fx = fx > 0 ? fx : 0.78125 * width;
  camera.fy = fy > 0 ? fy : camera.fx;
  // OpenCV's convention: pixel centres at integers, so the image centre is
  // at (width - 1) / 2.
  camera.cx = (width - 1) / 2.0;
  camera.cy = (height - 1) / 2.0;
  camera.distortion = distortion;
  return camera;
}

}  // namespace tagsfm::synth
