// Detection speed (ms per frame) and recall on video-like synthetic frames
// with about 20 tags, at 1280x720 and 1920x1080, for: this detector on full
// frames, its tracking mode, plain libapriltag (its defaults, and at
// quad_decimate 2 with 2 threads) and OpenCV contrib aruco with
// DICT_APRILTAG_36h11 -- all in the same run. Prints JSON.
//
// Every method reports wall and CPU ms per frame (CPU: all threads of the
// process, robust to other load on the machine) and its speed-up over both
// libapriltag baselines in each.
//
//   build/bench/detect_bench [frames] [only] [margin]
//
// frames: per resolution (default 40). only: run just the methods whose
// name contains this string, plus the libapriltag decimate 2 x 2 threads
// baseline (for profiling one method, e.g. "tagsfm_tracking"; "" for all).
// margin: white modules round each tag's black square (default 1, the
// official image printed edge to edge; runs before the option had 2).
#include <apriltag/apriltag.h>
#include <apriltag/tag36h11.h>

#include <chrono>
#include <ctime>
#include <cstdio>
#include <functional>
#include <iostream>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>
#include <opencv2/aruco.hpp>

#include "tagsfm/detect/apriltag_worker_pool.h"
#include "tagsfm/detect/synthetic_tags.h"
#include "tagsfm/detect/tag_detector.h"
#include "tagsfm/detect/tag_layout.h"
#include "tagsfm/detect/tag_tracker.h"

namespace {

using tagsfm::PlacedTag;
using Clock = std::chrono::steady_clock;

struct Sequence {
  std::vector<std::vector<PlacedTag>> truth;
  std::vector<cv::Mat> frames;
};

Sequence MakeSequence(int width, int height, int frames, double margin) {
  Sequence s;
  const double side = 0.05 * height;  // 36 px at 720 lines: 4.5 px per module
  s.truth = tagsfm::VideoTagPlacements(width, height, 20, side, frames, 0.004 * width, 5);
  tagsfm::TagRenderOptions render;
  render.blur_sigma_px = 0.7;
  render.noise_sigma = 2.0;
  render.margin_modules = margin;
  for (int f = 0; f < frames; ++f) {
    render.seed = 1000 + f;
    s.frames.push_back(*tagsfm::RenderTags("tag36h11", width, height, s.truth[f], render));
  }
  return s;
}

struct MethodResult {
  double ms_per_frame = 0.0;
  double cpu_ms_per_frame = 0.0;  // all threads: robust to other load on the machine
  int found = 0;
  int truth = 0;
  int wrong = 0;
};

// Runs `detect` on every frame (ids returned), timing only the detection.
MethodResult Run(const Sequence& s, const std::function<std::vector<int>(const cv::Mat&, int)>& detect) {
  MethodResult r;
  double seconds = 0.0;
  double cpu_seconds = 0.0;
  for (size_t f = 0; f < s.frames.size(); ++f) {
    const auto start = Clock::now();
    const std::clock_t cpu_start = std::clock();
    const std::vector<int> ids = detect(s.frames[f], static_cast<int>(f));
    cpu_seconds += static_cast<double>(std::clock() - cpu_start) / CLOCKS_PER_SEC;
    seconds += std::chrono::duration<double>(Clock::now() - start).count();
    std::set<int> truth_ids;
    for (const PlacedTag& t : s.truth[f]) truth_ids.insert(t.id);
    r.truth += static_cast<int>(truth_ids.size());
    for (int id : std::set<int>(ids.begin(), ids.end())) (truth_ids.count(id) ? r.found : r.wrong)++;
  }
  r.ms_per_frame = 1000.0 * seconds / s.frames.size();
  r.cpu_ms_per_frame = 1000.0 * cpu_seconds / s.frames.size();
  return r;
}

std::function<std::vector<int>(const cv::Mat&, int)> PlainAprilTag(int threads, float decimate,
                                                                    std::shared_ptr<void>* keep) {
  apriltag_family_t* family = tag36h11_create();
  apriltag_detector_t* td = apriltag_detector_create();  // libapriltag's defaults
  apriltag_detector_add_family(td, family);
  if (threads > 0) td->nthreads = threads;
  if (decimate > 0) td->quad_decimate = decimate;
  tagsfm::StartAprilTagWorkerPool(td);  // libapriltag 3.3's first threaded run races with its threads' start
  *keep = std::shared_ptr<void>(td, [family](void* p) {
    apriltag_detector_destroy(static_cast<apriltag_detector_t*>(p));
    tag36h11_destroy(family);
  });
  return [td](const cv::Mat& gray, int) {
    image_u8_t im{gray.cols, gray.rows, static_cast<int32_t>(gray.step[0]), gray.data};
    zarray_t* detections = apriltag_detector_detect(td, &im);
    std::vector<int> ids;
    for (int i = 0; i < zarray_size(detections); ++i) {
      apriltag_detection_t* det;
      zarray_get(detections, i, &det);
      if (det->hamming == 0) ids.push_back(det->id);
    }
    apriltag_detections_destroy(detections);
    return ids;
  };
}

std::vector<int> Ids(const tagsfm::DetectionSet& set) {
  std::vector<int> ids;
  ids.reserve(set.tags.size());
  for (const tagsfm::TagDetection& t : set.tags) ids.push_back(t.id);
  return ids;
}

nlohmann::json ToJson(const MethodResult& r) {
  return {{"ms_per_frame", r.ms_per_frame},
          {"cpu_ms_per_frame", r.cpu_ms_per_frame},
          {"recall", r.truth > 0 ? static_cast<double>(r.found) / r.truth : 0.0},
          {"tags_found", r.found},
          {"tags_in_view", r.truth},
          {"wrong_ids", r.wrong}};
}

using Detect = std::function<std::vector<int>(const cv::Mat&, int)>;
using Results = std::map<std::string, MethodResult>;

// The command line: [frames] [only] [margin] (see the top of this file).
struct BenchOptions {
  int frames = 40;
  std::string only;
  double margin = 1.0;

  // The decimate 2 x 2 threads baseline always runs: every speed-up is over it.
  bool Wanted(const std::string& name) const {
    return name == "libapriltag_decimate2_threads2" || name.find(only) != std::string::npos;
  }
};

// Nothing (after a message on stderr) when the margin is out of range.
std::optional<BenchOptions> ParseOptions(int argc, char** argv) {
  BenchOptions options;
  options.frames = argc > 1 ? std::max(2, std::atoi(argv[1])) : 40;
  options.only = argc > 2 ? argv[2] : "";
  options.margin = argc > 3 ? std::atof(argv[3]) : 1.0;
  if (!(options.margin >= 1.0 && options.margin <= 10.0)) {
    std::cerr << "margin must be in 1..10 modules (got " << (argc > 3 ? argv[3] : "") << ")\n";
    return std::nullopt;
  }
  return options;
}

// Runs the wanted methods on one resolution's frames and keeps their results
// by method name.
struct Measurements {
  const Sequence& sequence;
  const BenchOptions& options;
  Results results;

  void Measure(const std::string& name, const Detect& detect) {
    if (options.Wanted(name)) results[name] = Run(sequence, detect);
  }
};

// What the methods of one resolution detect with. Each is made just before its
// method runs, and all live until the resolution's report (which reads the
// tracker's stats), so the threads they own neither come nor go while another
// method is timed.
struct Detectors {
  std::unique_ptr<tagsfm::TagDetector> full_frame;
  std::unique_ptr<tagsfm::TagDetector> full_frame_unrefined;
  std::unique_ptr<tagsfm::TagTracker> tracker;
  std::unique_ptr<tagsfm::TagTracker> tracker_libapriltag_bands;
  std::unique_ptr<tagsfm::TagTracker> tracker_no_bands;
  std::unique_ptr<tagsfm::TagTracker> tracker_unrefined;
  std::shared_ptr<void> keep_libapriltag_defaults;
  std::shared_ptr<void> keep_libapriltag_d2t2;
  cv::Ptr<cv::aruco::Dictionary> aruco_dictionary;
  cv::Ptr<cv::aruco::DetectorParameters> aruco_parameters;
};

// The ids a full-frame detection (or a tracked frame) found; none when it failed.
Detect DetectWith(tagsfm::TagDetector* detector) {
  return [detector](const cv::Mat& gray, int f) {
    const tagsfm::Result<tagsfm::DetectionSet> found = detector->Detect(gray, f);
    return found ? Ids(*found) : std::vector<int>{};
  };
}

Detect TrackWith(tagsfm::TagTracker* tracker) {
  return [tracker](const cv::Mat& gray, int f) {
    const tagsfm::Result<tagsfm::DetectionSet> found = tracker->Track(gray, f);
    return found ? Ids(*found) : std::vector<int>{};
  };
}

// This detector on full frames and in its tracking mode, each with and
// without its corner refinement, and tracking without its own entry bands.
void MeasureTagsfm(Measurements* m, Detectors* d) {
  d->full_frame = *tagsfm::TagDetector::Create(tagsfm::TagDetectorOptions{});
  m->Measure("tagsfm_full_frame", DetectWith(d->full_frame.get()));
  tagsfm::TagDetectorOptions unrefined;
  unrefined.refinement = tagsfm::CornerRefinement::kNone;
  d->full_frame_unrefined = *tagsfm::TagDetector::Create(unrefined);
  m->Measure("tagsfm_full_frame_without_refinement", DetectWith(d->full_frame_unrefined.get()));
  d->tracker = *tagsfm::TagTracker::Create(tagsfm::TagDetectorOptions{}, tagsfm::TagTrackerOptions{});
  m->Measure("tagsfm_tracking", TrackWith(d->tracker.get()));
  tagsfm::TagTrackerOptions libapriltag_bands;
  libapriltag_bands.entry_band_candidates = false;
  d->tracker_libapriltag_bands = *tagsfm::TagTracker::Create(tagsfm::TagDetectorOptions{}, libapriltag_bands);
  m->Measure("tagsfm_tracking_bands_by_libapriltag", TrackWith(d->tracker_libapriltag_bands.get()));
  tagsfm::TagTrackerOptions no_bands;
  no_bands.search_entry_bands = false;
  d->tracker_no_bands = *tagsfm::TagTracker::Create(tagsfm::TagDetectorOptions{}, no_bands);
  m->Measure("tagsfm_tracking_without_entry_bands", TrackWith(d->tracker_no_bands.get()));
  d->tracker_unrefined = *tagsfm::TagTracker::Create(unrefined, tagsfm::TagTrackerOptions{});
  m->Measure("tagsfm_tracking_without_refinement", TrackWith(d->tracker_unrefined.get()));
}

// The baselines: libapriltag (its defaults, and decimate 2 with 2 threads)
// and OpenCV contrib aruco.
void MeasureBaselines(Measurements* m, Detectors* d) {
  // The libapriltag detectors are made (and their threads started) even when
  // their method is not wanted.
  m->Measure("libapriltag_defaults", PlainAprilTag(0, 0.0f, &d->keep_libapriltag_defaults));
  m->Measure("libapriltag_decimate2_threads2", PlainAprilTag(2, 2.0f, &d->keep_libapriltag_d2t2));

  d->aruco_dictionary = cv::aruco::getPredefinedDictionary(cv::aruco::DICT_APRILTAG_36h11);
  d->aruco_parameters = cv::aruco::DetectorParameters::create();
  m->Measure("opencv_aruco_apriltag36h11", [d](const cv::Mat& gray, int) {
    std::vector<std::vector<cv::Point2f>> corners;
    std::vector<int> ids;
    cv::aruco::detectMarkers(gray, d->aruco_dictionary, corners, ids, d->aruco_parameters);
    return ids;
  });
}

// The edge-line fit alone, per tag, from corners 0.3 px off the truth
// (CPU time: it runs on this one thread); 0 when not wanted.
double EdgeLineFitMsPerTag(const Sequence& s, const BenchOptions& options) {
  int refined = 0;
  const std::clock_t fit_start = std::clock();
  for (size_t f = 0; f < s.frames.size() && options.Wanted("edge_line_fit"); ++f) {
    for (const PlacedTag& tag : s.truth[f]) {
      tagsfm::QuadCorners corners = tag.corners;
      for (auto& c : corners) c += Eigen::Vector2d(0.3, -0.2);
      refined += tagsfm::RefineCornersByEdgeLines(s.frames[f], *tagsfm::MakeTagLayout("tag36h11", tag.id), &corners);
    }
  }
  const double fit_ms = 1000.0 * static_cast<double>(std::clock() - fit_start) / CLOCKS_PER_SEC;
  return refined > 0 ? fit_ms / refined : 0.0;
}

// Each method's result under its name, with its speed-ups over the two
// libapriltag baselines (baseline ms / method ms; > 1: the method is faster),
// in wall time and in CPU time of all threads.
void AddMethodResults(const Results& results, nlohmann::json* res) {
  const MethodResult& d2t2 = results.at("libapriltag_decimate2_threads2");  // always run
  for (const auto& [name, r] : results) {
    nlohmann::json j = ToJson(r);
    if (results.count("libapriltag_defaults")) {
      const MethodResult& defaults = results.at("libapriltag_defaults");
      j["speedup_over_libapriltag_defaults"] = {{"wall", defaults.ms_per_frame / r.ms_per_frame},
                                                {"cpu", defaults.cpu_ms_per_frame / r.cpu_ms_per_frame}};
    }
    j["speedup_over_libapriltag_decimate2_threads2"] = {{"wall", d2t2.ms_per_frame / r.ms_per_frame},
                                                        {"cpu", d2t2.cpu_ms_per_frame / r.cpu_ms_per_frame}};
    (*res)[name] = j;
  }
  if (results.count("tagsfm_full_frame") && results.count("tagsfm_tracking")) {
    (*res)["tracking_recall_over_full_frame_recall"] =
        static_cast<double>(results.at("tagsfm_tracking").found) / std::max(1, results.at("tagsfm_full_frame").found);
  }
}

// Where the default tracking mode found its tags, and its time per frame in
// each kind of search.
nlohmann::json TrackingStatsJson(const tagsfm::TagTrackerStats& stats) {
  const double per_frame = 1.0 / std::max(1, stats.frames);
  return {{"frames", stats.frames},
          {"full_frame_detections", stats.full_frame_detections},
          {"recoveries", stats.recoveries},
          {"backed_off", stats.backed_off},
          {"region_detections", stats.region_detections},
          {"band_detections", stats.band_detections},
          {"tags_found_in_bands", stats.tags_found_in_bands},
          {"region_cpu_ms_per_frame", stats.region_cpu_ms * per_frame},
          {"band_cpu_ms_per_frame", stats.band_cpu_ms * per_frame},
          {"refine_wall_ms_per_frame", stats.refine_ms * per_frame},
          {"full_frame_wall_ms_per_frame", stats.full_frame_ms * per_frame}};
}

// One resolution: renders its frames, runs the wanted methods on them and
// returns its report.
nlohmann::json BenchResolution(int width, int height, const BenchOptions& options) {
  std::fprintf(stderr, "rendering %dx%d...\n", width, height);
  const Sequence s = MakeSequence(width, height, options.frames, options.margin);
  Measurements m{s, options, {}};
  Detectors d;
  MeasureTagsfm(&m, &d);
  MeasureBaselines(&m, &d);
  const double edge_line_fit_ms_per_tag = EdgeLineFitMsPerTag(s, options);

  nlohmann::json res;
  res["edge_line_fit_ms_per_tag"] = edge_line_fit_ms_per_tag;
  AddMethodResults(m.results, &res);
  res["tracking_stats"] = TrackingStatsJson(d.tracker->stats());
  return res;
}

}  // namespace

int main(int argc, char** argv) {
  const std::optional<BenchOptions> options = ParseOptions(argc, argv);
  if (!options) return 2;
  nlohmann::json out;
  out["frames_per_resolution"] = options->frames;
  out["margin_modules"] = options->margin;
  out["scene"] = "VideoTagPlacements: 20 tag36h11 tags, side 0.05*height, tilt <= 50 deg, panning 0.4% of width "
                 "per frame, blur 0.7 px, noise 2 grey levels";
  for (const auto& [width, height] : std::vector<std::pair<int, int>>{{1280, 720}, {1920, 1080}}) {
    out[std::to_string(width) + "x" + std::to_string(height)] = BenchResolution(width, height, *options);
  }
  std::cout << out.dump(2) << std::endl;
  return 0;
}
