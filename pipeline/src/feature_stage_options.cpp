#include <string>
#include <string_view>

#include "tagsfm/pipeline/feature_stage.h"

namespace tagsfm {
namespace {

// feature/'s Check()s name their fields by their own prefix; the message
// names them by their place under `features:` (pipeline_options.cpp adds
// "pipeline.").
Status Renamed(Status status, std::string_view own_prefix, const std::string& place) {
  if (status) return status;
  std::string message = status.error().message;
  if (message.rfind(own_prefix, 0) == 0) message.erase(0, own_prefix.size());
  return MakeError(place + message);
}

}  // namespace

Status FeatureStageOptions::Check() const {
  if (Status s = Renamed(extractor.Check(), "features.", "features.extractor."); !s) return s;
  if (Status s = Renamed(map.matcher.Check(), "matcher.", "features.map.matcher."); !s) return s;
  if (Status s = Renamed(map.triangulation.Check(), "triangulation.", "features.map.triangulation."); !s) return s;
  if (Status s = Renamed(map.Check(), "feature_map.", "features.map."); !s) return s;
  if (max_queued_keyframes < 1) return MakeError("features.max_queued_keyframes must be >= 1");
  if (max_feature_image_side < 0) return MakeError("features.max_feature_image_side must be >= 0");
  if (!(depth_range_factor > 1 && depth_range_factor < 1e3)) return MakeError("features.depth_range_factor must be in (1, 1000)");
  if (!(fallback_near_m > 0)) return MakeError("features.fallback_near_m must be > 0");
  if (!(fallback_far_m > fallback_near_m && fallback_far_m < 1e6)) {
    return MakeError("features.fallback_far_m must be above fallback_near_m (and finite)");
  }
  if (!(live_cloud_interval_s >= 0 && live_cloud_interval_s < 1e6)) return MakeError("features.live_cloud_interval_s must be >= 0");
  if (live_cloud_max_points < 0) return MakeError("features.live_cloud_max_points must be >= 0");
  if (finish_threads < 1 || finish_threads > 64) return MakeError("features.finish_threads must be in [1, 64]");
  if (match_threads < 1 || match_threads > 64) return MakeError("features.match_threads must be in [1, 64]");
  return Status::Ok();
}

}  // namespace tagsfm
