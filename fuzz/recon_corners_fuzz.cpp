// Detection -> pose -> map fed with arbitrary corner sets: a few frames of
// tags whose corners are either projections of a small two-wall scene from a
// camera pose the input chooses (plus input-chosen noise, so registration,
// mapping and the sliding window run) or raw doubles (NaN, infinities, huge
// values); tag ids repeat within a frame at will. Optionally against a known
// map. Then Finish (the final adjustment).
#include <fuzzer/FuzzedDataProvider.h>

#include <cmath>
#include <cstring>

#include "tagsfm/recon/reconstructor.h"
#include "tagsfm/recon/tag_geometry.h"

namespace {

using namespace tagsfm;

constexpr double kTagSize = 0.1;
constexpr int kTags = 8;

// Tags 0-3 on the floor (z = 0), 4-7 on a wall (y = 0.6) facing the camera.
Rigid3d WorldFromTag(int id) {
  if (id < 4) return Rigid3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.2 * (id % 2), 0.2 * (id / 2), 0));
  const Eigen::Quaterniond wall(Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitX()));
  return Rigid3d(wall, Eigen::Vector3d(0.2 * (id % 2), 0.6, 0.2 * ((id - 4) / 2)));
}

double AnyDouble(FuzzedDataProvider& in) {
  double v = 0;
  const auto bytes = in.ConsumeBytes<uint8_t>(sizeof v);
  if (!bytes.empty()) std::memcpy(&v, bytes.data(), bytes.size());  // data() may be null
  return v;
}

TagDetection MakeTag(FuzzedDataProvider& in, const CameraModel& camera, const Rigid3d& cam_from_world) {
  TagDetection tag;
  tag.id = in.ConsumeIntegralInRange(0, kTags);  // kTags itself: a tag of no scene
  tag.decision_margin = in.ConsumeFloatingPointInRange(0.0, 200.0);
  const bool raw = in.ConsumeIntegralInRange(0, 7) == 0;
  const TagCorners world = TagCornersInWorld(WorldFromTag(tag.id % kTags), kTagSize);
  for (int c = 0; c < 4; ++c) {
    if (raw) {
      tag.corners[c] = Eigen::Vector2d(AnyDouble(in), AnyDouble(in));
    } else {
      const Eigen::Vector3d p = cam_from_world * world[c];
      const Eigen::Vector2d noise(in.ConsumeFloatingPointInRange(-2.0, 2.0), in.ConsumeFloatingPointInRange(-2.0, 2.0));
      tag.corners[c] = camera.Project(p) + noise;
    }
  }
  return tag;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  FuzzedDataProvider in(data, size);
  CameraModel camera;
  camera.width = 640;
  camera.height = 480;
  camera.fx = camera.fy = 500;
  camera.cx = 319.5;
  camera.cy = 239.5;
  if (in.ConsumeBool()) camera.distortion = {-0.1, 0.02, 0, 0};
  TargetConfig targets;
  targets.size_m = kTagSize;
  std::optional<TargetCornerMap> known;
  if (in.ConsumeBool()) {
    known.emplace();
    for (int id = 0; id < 4; ++id) (*known)[id] = TagCornersInWorld(WorldFromTag(id), kTagSize);
  }
  ReconstructorOptions options;
  options.ba.global_iterations = 10;  // bounds one input's time
  options.ba.global_threads = 1;
  auto recon = Reconstructor::Create(camera, targets, known, options);
  if (!recon) return 0;
  const int frames = in.ConsumeIntegralInRange(0, 6);
  for (int f = 0; f < frames; ++f) {
    // Camera about 1 m in front of the scene, looking at it, moved and turned by the input.
    const Eigen::Vector3d centre(in.ConsumeFloatingPointInRange(-1.0, 1.0), in.ConsumeFloatingPointInRange(-1.5, 0.0),
                                 in.ConsumeFloatingPointInRange(0.1, 1.5));
    const Eigen::Quaterniond look = Eigen::Quaterniond(Eigen::AngleAxisd(-2.0, Eigen::Vector3d::UnitX())) *
                                    Eigen::Quaterniond(Eigen::AngleAxisd(in.ConsumeFloatingPointInRange(-0.5, 0.5),
                                                                         Eigen::Vector3d::UnitY()));
    const Rigid3d cam_from_world(look, -(look * centre));
    DetectionSet set;
    set.frame = f;
    const int tags = in.ConsumeIntegralInRange(0, 10);
    for (int t = 0; t < tags; ++t) set.tags.push_back(MakeTag(in, camera, cam_from_world));
    (void)(*recon)->AddFrame(set);
    (void)(*recon)->PredictTagCorners(f + 1);
  }
  (void)(*recon)->Finish();
  return 0;
}
