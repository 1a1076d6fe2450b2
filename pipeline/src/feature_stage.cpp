#include "tagsfm/pipeline/feature_stage.h"

#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <deque>
#include <future>
#include <map>
#include <mutex>
#include <set>
#include <thread>

#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <opencv2/core/utility.hpp>

namespace tagsfm {
namespace {

using Clock = std::chrono::steady_clock;

double SecondsSince(Clock::time_point start) { return std::chrono::duration<double>(Clock::now() - start).count(); }

// A selected keyframe as the reconstruction saw it when it was selected.
struct Keyframe {
  FrameId frame = 0;
  Rigid3d cam_from_world;
  DepthRange depth;
  DetectionSet tags;
};

struct Job {
  Keyframe keyframe;
  cv::Mat gray, colour;
};

}  // namespace

struct FeatureStage::State {
  CameraModel camera;
  FeatureStageOptions options;
  FeatureExtractorOptions extractor;  // options.extractor with the image scale for large images
  bool live_cloud = false;
  std::vector<Keyframe> keyframes;    // in the order selected (frame loop only)
  std::optional<DepthRange> last_depth;
  // The map is the worker's while it runs, the caller's otherwise.
  std::unique_ptr<FeatureMap> map;
  Clock::time_point last_cloud;  // long ago: the first cloud as soon as there are points
  double last_cloud_s = 0;

  mutable std::mutex mutex;  // guards what follows
  std::condition_variable ready;
  std::deque<Job> queue;
  bool stopping = false;
  int dropped = 0;
  int rematched = 0;
  std::set<FrameId> failed;  // keyframes whose features could not be extracted or added
  std::vector<std::string> warnings;
  std::vector<double> keyframe_ms;
  LiveCloud cloud;
  std::thread worker;
  int opencv_threads = 0;  // OpenCV's threads before the worker started

  // Without the worker: the newest keyframe's features, extracted on a
  // thread of their own while the keyframe before is matched and the next
  // frames are read and detected (SIFT's serial parts left a core idle).
  // It joins the map, in order, when the next keyframe comes or the map is
  // read (AddPending).
  struct Extracted {
    Result<KeyframeFeatures> features;
    double ms = 0;  // the extraction's time
  };
  struct Pending {
    Keyframe keyframe;
    std::future<Extracted> extracted;  // features and time come back here: the thread writes nothing else the main thread reads
  };
  std::unique_ptr<Pending> pending;
  void AddPending();

  void Work();
  // `threads` match the keyframe with its neighbours: one on the live
  // worker (the other core is capture's and the tags'), match_threads else.
  void Process(const Keyframe& keyframe, const cv::Mat& gray, const cv::Mat& colour, FeatureMap* into, int threads);
  void Add(const Keyframe& keyframe, KeyframeFeatures features, FeatureMap* into, int threads);
  // Adds features extracted in extraction_ms (or warns of their error) and
  // counts the keyframe's time.
  void AddExtracted(const Keyframe& keyframe, Result<KeyframeFeatures> features, double extraction_ms, FeatureMap* into,
                    int threads);
  void UpdateCloud();
  void Warn(FrameId frame, const std::string& what);
  void StopWorker();
};

void FeatureStage::State::Warn(FrameId frame, const std::string& what) {
  std::lock_guard<std::mutex> lock(mutex);
  warnings.push_back("frame " + std::to_string(frame) + ": features: " + what);
  failed.insert(frame);
}

void FeatureStage::State::Add(const Keyframe& keyframe, KeyframeFeatures features, FeatureMap* into, int threads) {
  auto added = into->AddKeyframe(std::move(features), keyframe.cam_from_world, keyframe.depth, threads);
  if (!added) Warn(keyframe.frame, added.error().message);
}

void FeatureStage::State::Process(const Keyframe& keyframe, const cv::Mat& gray, const cv::Mat& colour, FeatureMap* into,
                                  int threads) {
  const auto t0 = Clock::now();
  auto features = ExtractFeatures(gray, colour, keyframe.tags, extractor);
  AddExtracted(keyframe, std::move(features), SecondsSince(t0) * 1000.0, into, threads);
}

void FeatureStage::State::AddExtracted(const Keyframe& keyframe, Result<KeyframeFeatures> features, double extraction_ms,
                                       FeatureMap* into, int threads) {
  if (!features) {
    Warn(keyframe.frame, features.error().message);
    return;
  }
  const auto t0 = Clock::now();
  Add(keyframe, std::move(*features), into, threads);
  {
    std::lock_guard<std::mutex> lock(mutex);
    keyframe_ms.push_back(extraction_ms + SecondsSince(t0) * 1000.0);
  }
  if (into == map.get()) UpdateCloud();
}

void FeatureStage::State::AddPending() {
  if (!pending) return;
  std::unique_ptr<Pending> done = std::move(pending);
  Extracted extracted = done->extracted.get();
  AddExtracted(done->keyframe, std::move(extracted.features), extracted.ms, map.get(), options.match_threads);
}

// The live cloud: every track triangulated with the keyframes' poses as
// they were selected, at most every live_cloud_interval_s and at most a
// quarter of the time (triangulation grows with the tracks).
void FeatureStage::State::UpdateCloud() {
  if (!live_cloud) return;
  if (SecondsSince(last_cloud) < std::max(options.live_cloud_interval_s, 3.0 * last_cloud_s)) {
    std::lock_guard<std::mutex> lock(mutex);
    cloud.keyframes = map->keyframes();
    return;
  }
  const auto t0 = Clock::now();
  PoseMap poses;
  for (int k = 0; k < map->keyframes(); ++k) poses[map->keyframe(k).features.frame] = map->keyframe(k).cam_from_world;
  // Without the refinement: its cost grows with every track and would
  // stall the frames (found by the soak test); the final points have it.
  const std::vector<FeaturePoint> points = map->TriangulateCoarse(poses, camera);
  LiveCloud fresh;
  fresh.points = static_cast<int>(points.size());
  fresh.keyframes = map->keyframes();
  const size_t cap = static_cast<size_t>(options.live_cloud_max_points);
  const size_t stride = cap == 0 ? 0 : (points.size() + cap - 1) / cap;
  for (size_t i = 0; stride > 0 && i < points.size(); i += stride) fresh.sample.push_back(points[i].position.cast<float>());
  last_cloud = Clock::now();
  last_cloud_s = SecondsSince(t0);
  std::lock_guard<std::mutex> lock(mutex);
  fresh.dropped = dropped;
  cloud = std::move(fresh);
}

void FeatureStage::State::Work() {
  // Live, the features are best effort (a keyframe dropped here is done
  // again at Finish) and the frames' tags are not: this thread runs at a
  // lower priority (nice +10, Linux's per-thread nice), and OpenCV runs its
  // parallel loops in the calling thread while the worker lives, so SIFT
  // does not take the detector's core either (StopWorker restores it).
  setpriority(PRIO_PROCESS, static_cast<id_t>(syscall(SYS_gettid)), 10);
  while (true) {
    Job job;
    {
      std::unique_lock<std::mutex> lock(mutex);
      ready.wait(lock, [&] { return stopping || !queue.empty(); });
      if (queue.empty()) return;  // stopping, and every queued keyframe done
      job = std::move(queue.front());
      queue.pop_front();
    }
    Process(job.keyframe, job.gray, job.colour, map.get(), 1);
  }
}

void FeatureStage::State::StopWorker() {
  if (!worker.joinable()) return;
  {
    std::lock_guard<std::mutex> lock(mutex);
    stopping = true;
  }
  ready.notify_one();
  worker.join();
  cv::setNumThreads(opencv_threads);
}

Result<std::unique_ptr<FeatureStage>> FeatureStage::Create(const CameraModel& camera, const FeatureStageOptions& options,
                                                           bool live_cloud) {
  if (Status s = options.Check(); !s) return s.error();
  auto map = FeatureMap::Create(camera, options.map);
  if (!map) return map.error();
  auto state = std::make_unique<State>();
  state->camera = camera;
  state->options = options;
  state->extractor = options.extractor;
  const int side = std::max(camera.width, camera.height);
  if (options.max_feature_image_side > 0 && side > options.max_feature_image_side) {
    state->extractor.image_scale = std::min(state->extractor.image_scale, double(options.max_feature_image_side) / side);
  }
  state->live_cloud = live_cloud;
  state->map = std::make_unique<FeatureMap>(std::move(*map));
  if (options.background) {
    state->opencv_threads = cv::getNumThreads();
    cv::setNumThreads(1);
    state->worker = std::thread([s = state.get()] { s->Work(); });
  }
  return std::unique_ptr<FeatureStage>(new FeatureStage(std::move(state)));
}

FeatureStage::FeatureStage(std::unique_ptr<State> state) : state_(std::move(state)) {}

FeatureStage::~FeatureStage() {
  state_->StopWorker();
  if (state_->pending) state_->pending->extracted.wait();  // its thread reads the state
}

bool FeatureStage::SelectKeyframe(const FrameReport& report) const { return report.registered && report.keyframe; }

void FeatureStage::AddKeyframe(const Frame* frame, const DetectionSet& tags, const FrameReport& report,
                               const TargetCornerMap& mapped_corners) {
  State& s = *state_;
  const FeatureStageOptions& o = s.options;
  auto depth = TargetDepthRange(mapped_corners, report.cam_from_world, s.camera, o.depth_range_factor);
  if (!depth) depth = s.last_depth ? *s.last_depth : DepthRange{o.fallback_near_m, o.fallback_far_m};
  s.last_depth = depth;
  Keyframe keyframe{report.frame, report.cam_from_world, *depth, tags};
  s.keyframes.push_back(keyframe);
  if (!frame) return;  // Complete reads it again
  if (!s.worker.joinable()) {
    // One extraction at a time: each holds SIFT's scale space (~220 MB for
    // 1280x720). The previous keyframe's is waited for; this one's then
    // runs while the previous one is matched.
    if (s.pending) s.pending->extracted.wait();
    // Copies: the caller may reuse its buffers while the thread reads them.
    auto next = std::make_unique<State::Pending>();
    next->keyframe = keyframe;
    next->extracted = std::async(std::launch::async, [&s, tags = keyframe.tags, gray = frame->gray.clone(),
                                                      colour = frame->image.clone()] {
      const auto t0 = Clock::now();
      Result<KeyframeFeatures> features = ExtractFeatures(gray, colour, tags, s.extractor);
      return State::Extracted{std::move(features), SecondsSince(t0) * 1000.0};
    });
    s.AddPending();
    s.pending = std::move(next);
    return;
  }
  // Copies: the capture side may reuse its buffers.
  Job job{std::move(keyframe), frame->gray.clone(), frame->image.clone()};
  {
    std::lock_guard<std::mutex> lock(s.mutex);
    if (static_cast<int>(s.queue.size()) >= o.max_queued_keyframes) {
      s.queue.pop_front();  // the oldest waiting: the newest shows where the operator is
      ++s.dropped;
      s.cloud.dropped = s.dropped;
    }
    s.queue.push_back(std::move(job));
  }
  s.ready.notify_one();
}

void FeatureStage::Complete(const FeatureFrameLoader& reload) {
  State& s = *state_;
  s.StopWorker();
  s.AddPending();
  std::set<FrameId> failed;
  {
    std::lock_guard<std::mutex> lock(s.mutex);
    failed = s.failed;
  }
  // The worker took the keyframes in order: a map as long as the list (less
  // the failures) is the one a plain replay builds.
  if (static_cast<size_t>(s.map->keyframes()) + failed.size() >= s.keyframes.size()) return;
  std::map<FrameId, const KeyframeFeatures*> done;
  for (int k = 0; k < s.map->keyframes(); ++k) done[s.map->keyframe(k).features.frame] = &s.map->keyframe(k).features;
  auto rebuilt = std::make_unique<FeatureMap>(*FeatureMap::Create(s.camera, s.options.map));
  for (const Keyframe& keyframe : s.keyframes) {
    if (failed.count(keyframe.frame)) continue;
    if (const auto it = done.find(keyframe.frame); it != done.end()) {
      s.Add(keyframe, *it->second, rebuilt.get(), s.options.match_threads);
      continue;
    }
    auto frame = reload ? reload(keyframe.frame) : Result<Frame>(MakeError("no way to read it again"));
    if (!frame) {
      s.Warn(keyframe.frame, frame.error().message);
      continue;
    }
    s.Process(keyframe, frame->gray, frame->image, rebuilt.get(), s.options.match_threads);
  }
  s.map = std::move(rebuilt);
}

std::vector<FeaturePoint> FeatureStage::Triangulate(const PoseMap& cam_from_world, const CameraModel& camera,
                                                    FeatureTriangulationStats* stats) {
  state_->AddPending();
  if (state_->options.rematch_final_poses) {
    auto moved = state_->map->Rematch(cam_from_world, camera, state_->options.match_threads);
    std::lock_guard<std::mutex> lock(state_->mutex);
    if (moved) {
      state_->rematched = *moved;
    } else {
      state_->warnings.push_back("features: " + moved.error().message);
    }
  }
  return state_->map->Triangulate(cam_from_world, camera, state_->options.finish_threads, stats);
}

LiveCloud FeatureStage::live_cloud() const {
  std::lock_guard<std::mutex> lock(state_->mutex);
  return state_->cloud;
}

std::vector<std::string> FeatureStage::TakeWarnings() {
  std::lock_guard<std::mutex> lock(state_->mutex);
  return std::exchange(state_->warnings, {});
}

std::vector<double> FeatureStage::keyframe_ms() const {
  std::lock_guard<std::mutex> lock(state_->mutex);
  return state_->keyframe_ms;
}

int FeatureStage::dropped() const {
  std::lock_guard<std::mutex> lock(state_->mutex);
  return state_->dropped;
}

int FeatureStage::rematched() const {
  std::lock_guard<std::mutex> lock(state_->mutex);
  return state_->rematched;
}

}  // namespace tagsfm
