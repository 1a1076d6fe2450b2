#pragma once
// What the driver (replay, the daemon) measured around the reconstruction,
// reported in report.json beside the reconstruction's own figures.
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "tagsfm/core/csv_formats.h"
#include "tagsfm/feature/track_triangulation.h"

namespace tagsfm {

struct RunStats {
  int frames = 0;                       // frames in the input
  int frames_skipped = 0;               // unreadable images, skipped
  std::vector<std::pair<FrameId, std::string>> skipped;  // frame, why
  double runtime_s = 0;
  std::vector<double> frame_latency_ms; // reconstruction per frame, detection aside
  std::vector<double> detection_ms;     // detection per frame
  std::string tag_search;               // "tracking", "every_frame" (empty: not reported)
  int full_frame_detections = 0;        // frames detected in full (scheduled, first, after a lost tag)
  int tag_search_recoveries = 0;        // of those, after a tracked tag was not where predicted
  int fine_full_frame_detections = 0;   // of those, at full resolution: the tags in view were small
  std::vector<double> feature_ms;       // feature tracking per feature keyframe
  double triangulation_s = 0;           // feature points from the final poses (summed, when triangulated again)
  int feature_work_dropped = 0;         // feature keyframes not processed live (done at the end)
  int feature_keyframes_rematched = 0;  // matched again from their final poses (features.rematch_final_poses; the last triangulation's)
  FeatureTriangulationStats feature_triangulation;  // where the tracks went, last triangulation (report.json: why a cloud is thin)
  double peak_rss_mb = 0;
  std::map<FrameId, std::string> image_names;  // for colmap/images.txt
  std::string mode;                     // "known map", "no map", ...
};

}  // namespace tagsfm
