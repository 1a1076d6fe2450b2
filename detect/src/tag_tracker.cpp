#include "tagsfm/detect/tag_tracker.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include <Eigen/Dense>

#include "band_candidates.h"
#include "tagsfm/core/cpu_time.h"
#include "tag_detector_workers.h"

namespace tagsfm {

Status TagTrackerOptions::Check() const {
  if (full_frame_every < 1) return MakeError("full_frame_every must be >= 1 (got " + std::to_string(full_frame_every) + ")");
  if (!(full_frame_after_motion > 0.0)) return MakeError("full_frame_after_motion must be > 0");
  if (!(padding_px >= 0.0)) return MakeError("padding_px must be >= 0");
  if (!(padding_fraction >= 0.0)) return MakeError("padding_fraction must be >= 0");
  if (!(region_quad_decimate >= 1.0f)) return MakeError("region_quad_decimate must be >= 1");
  if (!(region_coarse_module_px >= 0.0)) return MakeError("region_coarse_module_px must be >= 0");
  if (!(entry_band_tag_sizes >= 0.0 && entry_band_tag_sizes <= 100.0)) {
    return MakeError("entry_band_tag_sizes must be in [0, 100]");
  }
  if (!(entry_band_margin_px >= 0.0)) return MakeError("entry_band_margin_px must be >= 0");
  if (!(entry_band_inflow_frames >= 1.0 && entry_band_inflow_frames <= 10.0)) {
    return MakeError("entry_band_inflow_frames must be in [1, 10]");
  }
  if (fine_search_below_tags < 0) return MakeError("fine_search_below_tags must be >= 0");
  if (!(entry_band_candidates_min_module_px >= 0.0)) {
    return MakeError("entry_band_candidates_min_module_px must be >= 0");
  }
  if (!(entry_min_inflow_px >= 0.0)) return MakeError("entry_min_inflow_px must be >= 0");
  return Status::Ok();
}

TagTracker::TagTracker(TagTrackerOptions options, std::unique_ptr<TagDetector> full,
                       std::unique_ptr<TagDetector> fine_full, std::vector<ThreadDetectors> per_thread,
                       std::unique_ptr<detail::BandCandidates> candidates)
    : options_(options),
      full_detector_(std::move(full)),
      fine_full_detector_(std::move(fine_full)),
      per_thread_(std::move(per_thread)),
      band_candidates_(std::move(candidates)),
      workers_(std::make_unique<detail::DetectionWorkers>(static_cast<int>(per_thread_.size()))) {}

TagTracker::~TagTracker() = default;

Result<std::unique_ptr<TagTracker>> TagTracker::Create(const TagDetectorOptions& detector,
                                                       const TagTrackerOptions& tracker) {
  if (Status status = tracker.Check(); !status) return status.error();
  auto full = TagDetector::Create(detector);
  if (!full) return full.error();
  std::unique_ptr<TagDetector> fine_full;
  if (tracker.region_quad_decimate < detector.quad_decimate) {
    TagDetectorOptions fine = detector;
    fine.quad_decimate = tracker.region_quad_decimate;
    auto created = TagDetector::Create(fine);
    if (!created) return created.error();
    fine_full = std::move(*created);
  }
  // Regions and bands give libapriltag's corners; the full detector refines
  // them all at once, on its threads.
  TagDetectorOptions part = detector;
  part.refine_edges = detector.refine_edges || detector.refinement == CornerRefinement::kAprilTag;
  part.refinement = CornerRefinement::kNone;
  part.threads = 1;  // parallel across regions, not inside one
  part.small_tag_pass = false;  // a full frame's pass (aruco over the whole image), not a region's
  part.drop_tags_cut_by_border = false;  // a region's edges are not the image's
  std::vector<ThreadDetectors> per_thread;
  for (int t = 0; t < detector.threads; ++t) {
    TagDetectorOptions region_options = part;
    region_options.quad_decimate = tracker.region_quad_decimate;
    auto region = TagDetector::Create(region_options);
    if (!region) return region.error();
    auto band = TagDetector::Create(part);
    if (!band) return band.error();
    per_thread.push_back({std::move(*region), std::move(*band)});
  }
  std::unique_ptr<detail::BandCandidates> candidates;
  if (tracker.entry_band_candidates) candidates = detail::BandCandidates::Create(detector.family);
  return std::unique_ptr<TagTracker>(
      new TagTracker(tracker, std::move(*full), std::move(fine_full), std::move(per_thread), std::move(candidates)));
}

void TagTracker::Reset() {
  tracks_.clear();
  have_full_ = false;
  recoveries_in_a_row_ = 0;
  full_frames_before_retry_ = 0;
}

std::map<TagId, QuadCorners> TagTracker::Predict(FrameId frame,
                                                 const std::map<TagId, QuadCorners>& predicted) const {
  std::map<TagId, QuadCorners> out = predicted;
  for (const auto& [id, track] : tracks_) {
    if (out.count(id)) continue;
    QuadCorners corners = track.corners;
    if (track.previous && track.frame != track.previous_frame) {
      const double steps = static_cast<double>(frame - track.frame) / static_cast<double>(track.frame - track.previous_frame);
      for (int k = 0; k < 4; ++k) corners[k] += steps * (track.corners[k] - (*track.previous)[k]);
    }
    out[id] = corners;
  }
  return out;
}

namespace {

double MsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace



void TagTracker::Update(const DetectionSet& detections) {
  std::map<TagId, TagTrack> next;
  std::vector<double> motion;  // px per frame of each tag seen before
  for (const TagDetection& tag : detections.tags) {
    TagTrack track;
    track.corners = tag.corners;
    track.frame = detections.frame;
    const auto old = tracks_.find(tag.id);
    if (old != tracks_.end()) {
      track.previous = old->second.corners;
      track.previous_frame = old->second.frame;
      if (track.frame > track.previous_frame) {
        Eigen::Vector2d shift = Eigen::Vector2d::Zero();
        for (int k = 0; k < 4; ++k) shift += 0.25 * (track.corners[k] - (*track.previous)[k]);
        motion.push_back(shift.norm() / static_cast<double>(track.frame - track.previous_frame));
      }
    }
    next[tag.id] = track;
  }
  tracks_ = std::move(next);
  if (!motion.empty()) {
    std::nth_element(motion.begin(), motion.begin() + motion.size() / 2, motion.end());
    motion_since_full_px_ += motion[motion.size() / 2];
  }
}

namespace {

// Bounding box of a quad: x0, y0, x1, y1.
Eigen::Vector4d BoundsOf(const QuadCorners& corners) {
  Eigen::Vector4d b(1e18, 1e18, -1e18, -1e18);
  for (const Eigen::Vector2d& c : corners) {
    b = Eigen::Vector4d(std::min(b[0], c.x()), std::min(b[1], c.y()), std::max(b[2], c.x()), std::max(b[3], c.y()));
  }
  return b;
}

// Extent of a quad: the larger side of its bounding box.
double ExtentOf(const QuadCorners& corners) {
  const Eigen::Vector4d b = BoundsOf(corners);
  return std::max(b[2] - b[0], b[3] - b[1]);
}

// The padded, clipped bounding box of predicted corners; empty when off-image.
cv::Rect RegionOf(const QuadCorners& corners, const TagTrackerOptions& options, const cv::Size& image) {
  const Eigen::Vector4d b = BoundsOf(corners);
  const double x0 = b[0], y0 = b[1], x1 = b[2], y1 = b[3];
  if (!(x1 >= x0 && y1 >= y0) || !std::isfinite(x0 + y0 + x1 + y1)) return {};
  const double pad = std::max(options.padding_px, options.padding_fraction * std::max(x1 - x0, y1 - y0));
  const int left = std::max(0, static_cast<int>(std::floor(x0 - pad)));
  const int top = std::max(0, static_cast<int>(std::floor(y0 - pad)));
  const int right = std::min(image.width, static_cast<int>(std::ceil(x1 + pad)) + 1);
  const int bottom = std::min(image.height, static_cast<int>(std::ceil(y1 + pad)) + 1);
  if (right <= left || bottom <= top) return {};
  return cv::Rect(left, top, right - left, bottom - top);
}

// A region to search and the smallest module size (px) of its tags.
struct Region {
  cv::Rect area;
  double module_px = 0.0;
};

// Mean side of a quad over `modules` modules.
double ModulePx(const QuadCorners& corners, int modules) {
  double sides = 0.0;
  for (int k = 0; k < 4; ++k) sides += (corners[(k + 1) % 4] - corners[k]).norm();
  return 0.25 * sides / std::max(1, modules);
}

// Overlapping regions merged, so that no tag is searched (and found) twice.
std::vector<Region> MergeOverlapping(std::vector<Region> regions) {
  bool merged = true;
  while (merged) {
    merged = false;
    for (size_t i = 0; i < regions.size() && !merged; ++i) {
      for (size_t j = i + 1; j < regions.size() && !merged; ++j) {
        if ((regions[i].area & regions[j].area).area() > 0) {
          regions[i].area |= regions[j].area;
          regions[i].module_px = std::min(regions[i].module_px, regions[j].module_px);
          regions.erase(regions.begin() + static_cast<long>(j));
          merged = true;
        }
      }
    }
  }
  return regions;
}

}  // namespace

namespace {

// A tag predicted wholly in view, its white quiet zone (about an eighth of
// its extent) included: one that is not found there is lost.
bool ExpectedInView(const QuadCorners& corners, const cv::Size& image) {
  return WhollyInsideImage(corners, image.width, image.height, 1.0 + ExtentOf(corners) / 8.0);
}

}  // namespace

// The image motion per frame is fitted to the tracked tags' last corner
// displacements: an affine flow field d(x) = M x + t with three tags or more
// (pan, roll and zoom all show in it), a translation with fewer. A border
// gets a band where d points into the image by entry_min_inflow_px somewhere
// along it; every border does while no tag has been seen twice.
void TagTracker::AddEntryBands(const cv::Size& image, std::vector<Search>* searches) const {
  std::vector<Eigen::Vector2d> points, flows;
  std::set<TagId> moving_tags;
  double largest = 0.0, smallest_module_px = 1e18;
  const int modules = full_detector_->ModulesAcrossCornerSquare();
  for (const auto& [id, track] : tracks_) {
    largest = std::max(largest, ExtentOf(track.corners));
    smallest_module_px = std::min(smallest_module_px, ModulePx(track.corners, modules));
    if (!track.previous || track.frame == track.previous_frame) continue;
    moving_tags.insert(id);
    const double dt = static_cast<double>(track.frame - track.previous_frame);
    for (int k = 0; k < 4; ++k) {
      points.push_back(track.corners[k]);
      flows.push_back((track.corners[k] - (*track.previous)[k]) / dt);
    }
  }
  if (largest <= 0.0) return;
  // No tag seen twice yet (the first frame after the first full-frame
  // pass): the motion is unknown, so every border gets a band.
  const bool motion_known = !points.empty();
  Eigen::Matrix2d m = Eigen::Matrix2d::Zero();
  Eigen::Vector2d t = Eigen::Vector2d::Zero();
  for (const Eigen::Vector2d& f : flows) t += f;
  if (motion_known) t /= static_cast<double>(flows.size());
  if (moving_tags.size() >= 3) {
    // Least squares for [M t] on centred coordinates (well conditioned).
    Eigen::Vector2d mean = Eigen::Vector2d::Zero();
    for (const Eigen::Vector2d& p : points) mean += p;
    mean /= static_cast<double>(points.size());
    Eigen::Matrix3d normal = Eigen::Matrix3d::Zero();
    Eigen::Matrix<double, 3, 2> rhs = Eigen::Matrix<double, 3, 2>::Zero();
    for (size_t i = 0; i < points.size(); ++i) {
      const Eigen::Vector3d a((points[i] - mean).x(), (points[i] - mean).y(), 1.0);
      normal += a * a.transpose();
      rhs += a * flows[i].transpose();
    }
    const Eigen::Matrix<double, 3, 2> x = normal.ldlt().solve(rhs);
    if (x.allFinite()) {
      m = x.topRows<2>().transpose();
      t = x.row(2).transpose() - m * mean;
    }
  }
  const auto flow_at = [&](double px, double py) { return Eigen::Vector2d(m * Eigen::Vector2d(px, py) + t); };
  const double w = image.width - 1.0, h = image.height - 1.0;
  struct Border {
    Eigen::Vector2d a, b, inward;
  };
  const Border borders[4] = {{{0, 0}, {0, h}, {1, 0}},    // left
                             {{w, 0}, {w, h}, {-1, 0}},   // right
                             {{0, 0}, {w, 0}, {0, 1}},    // top
                             {{0, h}, {w, h}, {0, -1}}};  // bottom
  for (int side = 0; side < 4; ++side) {
    const Border& border = borders[side];
    double inflow = -1e18;
    for (int i = 0; i <= 8; ++i) {  // the flow is affine: its extremes are at the ends; 9 samples for clarity
      const Eigen::Vector2d p = border.a + (border.b - border.a) * (i / 8.0);
      inflow = std::max(inflow, flow_at(p.x(), p.y()).dot(border.inward));
    }
    // Unknown motion: no flow (m and t zero), inflow 0, and a band all the same.
    if (motion_known && !(inflow >= options_.entry_min_inflow_px)) continue;
    const int width = static_cast<int>(std::ceil(options_.entry_band_tag_sizes * largest +
                                                 options_.entry_band_inflow_frames * std::max(inflow, 0.0) +
                                                 options_.entry_band_margin_px));
    cv::Rect band;
    switch (side) {
      case 0: band = cv::Rect(0, 0, width, image.height); break;
      case 1: band = cv::Rect(image.width - width, 0, width, image.height); break;
      case 2: band = cv::Rect(0, 0, image.width, width); break;
      default: band = cv::Rect(0, image.height - width, image.width, width); break;
    }
    band &= cv::Rect(0, 0, image.width, image.height);
    // Tags entering are taken to be about as small as the smallest in view.
    const bool by_candidates =
        band_candidates_ != nullptr && smallest_module_px >= options_.entry_band_candidates_min_module_px;
    const bool coarse = !FewAndSmall(tracks_.size(), smallest_module_px);
    if (band.area() > 0) searches->push_back(Search{band, true, coarse, by_candidates, {}});
  }
}

// libapriltag on the search's area (a view of the frame: no copy), tags in
// frame coordinates appended to search->found.
Status TagTracker::SearchArea(const cv::Mat& gray8, FrameId frame, int thread, Search* search) const {
  TagDetector& detector = search->coarse ? *per_thread_[thread].band : *per_thread_[thread].region;
  auto found = detector.Detect(gray8(search->area), frame);
  if (!found) return found.error();
  const Eigen::Vector2d offset(search->area.x, search->area.y);
  for (TagDetection& tag : found->tags) {
    for (Eigen::Vector2d& c : tag.corners) c += offset;
    search->found.push_back(std::move(tag));
  }
  return Status::Ok();
}

// An entry band by candidates (detail::BandCandidates): libapriltag only in
// a padded region around each candidate outside the tracked regions.
Status TagTracker::SearchBandCandidates(const cv::Mat& gray8, FrameId frame, const std::vector<cv::Rect>& regions,
                                        int thread, Search* band) const {
  const Eigen::Vector2d offset(band->area.x, band->area.y);
  const int modules = full_detector_->ModulesAcrossCornerSquare();
  // A candidate wholly inside a tracked region (its quiet zone included)
  // is found there.
  TagTrackerOptions unpadded = options_;
  unpadded.padding_px = 2.0;
  unpadded.padding_fraction = 0.125;
  for (QuadCorners corners : band_candidates_->Find(gray8(band->area))) {
    for (Eigen::Vector2d& c : corners) c += offset;
    Search candidate{RegionOf(corners, options_, gray8.size()), true, false, false, {}};
    if (candidate.area.area() <= 0) continue;
    const cv::Rect tag_box = RegionOf(corners, unpadded, gray8.size());
    const bool in_region = std::any_of(regions.begin(), regions.end(),
                                       [&](const cv::Rect& region) { return (region & tag_box) == tag_box; });
    if (in_region) continue;
    candidate.coarse = ModulePx(corners, modules) >= options_.region_coarse_module_px;
    if (Status status = SearchArea(gray8, frame, thread, &candidate); !status) return status;
    for (TagDetection& tag : candidate.found) band->found.push_back(std::move(tag));
  }
  return Status::Ok();
}

// One tracked tag searched in its region at region_quad_decimate (on the
// caller's thread: no job runs now), appended to `found` if there.
Status TagTracker::SearchFine(const cv::Mat& gray8, FrameId frame, TagId id, const QuadCorners& corners,
                              std::vector<TagDetection>* found) {
  Search region{RegionOf(corners, options_, gray8.size()), false, false, false, {}};
  if (region.area.area() <= 0) return Status::Ok();
  ++stats_.region_detections;
  if (Status status = SearchArea(gray8, frame, 0, &region); !status) return status;
  for (TagDetection& tag : region.found) {
    if (tag.id == id) found->push_back(std::move(tag));
  }
  return Status::Ok();
}

// A full-frame detection, plus the tracked tags (not the caller's hints) it
// missed that their regions still find. Regions of small tags run at
// region_quad_decimate and find tags the full frame (at the detector's decimation) misses; a
// full-frame pass must not drop them (it did: 24 px tags, 7 of 244
// sightings, TagTrackerSlow.SmallTagsEnterOnTime).
Result<DetectionSet> TagTracker::DetectFullFrame(const cv::Mat& gray8, FrameId frame,
                                                 const std::map<TagId, QuadCorners>& expected) {
  ++stats_.full_frame_detections;
  frames_since_full_ = 0;
  motion_since_full_px_ = 0.0;
  have_full_ = true;
  const auto start = std::chrono::steady_clock::now();
  Result<DetectionSet> detections = DetectWholeImage(gray8, frame);
  if (!detections) return detections;
  std::set<TagId> found;
  for (const TagDetection& tag : detections->tags) found.insert(tag.id);
  std::vector<TagDetection> kept;
  for (const auto& [id, corners] : expected) {
    if (found.count(id) || !tracks_.count(id) || !ExpectedInView(corners, gray8.size())) continue;
    if (Status status = SearchFine(gray8, frame, id, corners, &kept); !status) return status.error();
  }
  if (!kept.empty()) {
    full_detector_->RefineDetections(gray8, &kept);
    for (TagDetection& tag : kept) detections->tags.push_back(std::move(tag));
    std::sort(detections->tags.begin(), detections->tags.end(),
              [](const TagDetection& a, const TagDetection& b) { return a.id < b.id; });
  }
  stats_.full_frame_ms += MsSince(start);
  return detections;
}

// Fewer than fine_search_below_tags tags, the smallest with modules under
// region_coarse_module_px: the coarse decimation has likely missed others as small.
bool TagTracker::FewAndSmall(size_t tags, double smallest_module_px) const {
  return static_cast<int>(tags) < options_.fine_search_below_tags && smallest_module_px < options_.region_coarse_module_px;
}

bool TagTracker::FewSmallTags(const std::vector<TagDetection>& found) const {
  const int modules = full_detector_->ModulesAcrossCornerSquare();
  double smallest = std::numeric_limits<double>::infinity();
  for (const TagDetection& tag : found) smallest = std::min(smallest, ModulePx(tag.corners, modules));
  return FewAndSmall(found.size(), smallest);
}

// The same test on the tags found on the last frame.
bool TagTracker::FewSmallTracked() const {
  const int modules = full_detector_->ModulesAcrossCornerSquare();
  double smallest = std::numeric_limits<double>::infinity();
  for (const auto& [id, track] : tracks_) smallest = std::min(smallest, ModulePx(track.corners, modules));
  return FewAndSmall(tracks_.size(), smallest);
}

// The whole image at the detector's decimation, or at region_quad_decimate
// when few, small tags are in view or found there.
Result<DetectionSet> TagTracker::DetectWholeImage(const cv::Mat& gray8, FrameId frame) {
  if (fine_full_detector_ == nullptr) return full_detector_->Detect(gray8, frame);
  if (!FewSmallTracked()) {
    Result<DetectionSet> coarse = full_detector_->Detect(gray8, frame);
    if (!coarse || !FewSmallTags(coarse->tags)) return coarse;
  }
  ++stats_.fine_full_frame_detections;
  return fine_full_detector_->Detect(gray8, frame);
}

// The searches of a tracked frame into searches_: a region round each
// expected tag (overlapping ones merged), then the entry bands.
void TagTracker::PlanSearches(const cv::Size& image, const std::map<TagId, QuadCorners>& expected) {
  std::vector<Region> regions;
  const int modules = full_detector_->ModulesAcrossCornerSquare();
  for (const auto& [id, corners] : expected) {
    const cv::Rect area = RegionOf(corners, options_, image);
    if (area.area() > 0) regions.push_back(Region{area, ModulePx(corners, modules)});
  }
  searches_.clear();
  for (const Region& region : MergeOverlapping(std::move(regions))) {
    searches_.push_back(Search{region.area, false, region.module_px >= options_.region_coarse_module_px, false, {}});
  }
  const size_t region_count = searches_.size();
  if (options_.search_entry_bands) AddEntryBands(image, &searches_);
  stats_.region_detections += static_cast<int>(region_count);
  stats_.band_detections += static_cast<int>(searches_.size() - region_count);
}

// searches_ run on the worker threads, largest first, so that the threads
// finish together; their CPU time goes to the stats.
Status TagTracker::RunSearches(const cv::Mat& gray8, FrameId frame) {
  std::sort(searches_.begin(), searches_.end(),
            [](const Search& a, const Search& b) { return a.area.area() > b.area.area(); });
  std::vector<std::optional<Error>> errors(per_thread_.size());
  std::vector<double> region_cpu_ms(per_thread_.size(), 0.0), band_cpu_ms(per_thread_.size(), 0.0);
  std::vector<cv::Rect> region_areas;
  for (const Search& search : searches_) {
    if (!search.band) region_areas.push_back(search.area);
  }
  workers_->Run(static_cast<int>(searches_.size()), [&](int i, int thread) {
    Search& search = searches_[i];
    const double cpu_start = ThreadCpuMs();
    Status status = search.by_candidates ? SearchBandCandidates(gray8, frame, region_areas, thread, &search)
                                                    : SearchArea(gray8, frame, thread, &search);
    (search.band ? band_cpu_ms : region_cpu_ms)[thread] += ThreadCpuMs() - cpu_start;
    if (!status) errors[thread] = status.error();
  });
  for (const auto& error : errors) {
    if (error) return *error;
  }
  for (size_t t = 0; t < per_thread_.size(); ++t) {
    stats_.region_cpu_ms += region_cpu_ms[t];
    stats_.band_cpu_ms += band_cpu_ms[t];
  }
  return Status::Ok();
}

// The tags the searches found, moved out of searches_, their ids into
// `found_ids`: tracked regions first; from the bands only tags not found
// otherwise.
DetectionSet TagTracker::TakeFound(FrameId frame, std::set<TagId>* found_ids) {
  DetectionSet result;
  result.frame = frame;
  for (int pass = 0; pass < 2; ++pass) {
    for (Search& search : searches_) {
      if (search.band != (pass == 1)) continue;
      for (TagDetection& tag : search.found) {
        if (!found_ids->insert(tag.id).second) continue;
        if (search.band) ++stats_.tags_found_in_bands;
        result.tags.push_back(std::move(tag));
      }
    }
  }
  return result;
}

// A tag expected wholly in view but not found: a region at the
// detector's decimation misses some strongly tilted tags that
// region_quad_decimate finds (tilt 70 degrees: up to 4.4 px modules), so
// first look again there, appending to `found`; else the prediction failed
// (or the tag is hidden): *lost. A tag predicted across the border (its
// white quiet zone, about an eighth of its extent, included) has left the
// view: no search. A tag the caller predicted but the last frame did not
// have (turning into view, behind an occluder) is a hint: searched, but not
// missed.
Status TagTracker::SearchMissed(const cv::Mat& gray8, FrameId frame, const std::map<TagId, QuadCorners>& expected,
                                const std::set<TagId>& found_ids, std::vector<TagDetection>* found, bool* lost) {
  const int modules = full_detector_->ModulesAcrossCornerSquare();
  for (const auto& [id, corners] : expected) {
    if (found_ids.count(id) || !tracks_.count(id) || !ExpectedInView(corners, gray8.size())) continue;
    const size_t before = found->size();
    if (ModulePx(corners, modules) >= options_.region_coarse_module_px) {
      if (Status status = SearchFine(gray8, frame, id, corners, found); !status) return status;
    }
    if (found->size() == before) *lost = true;
  }
  return Status::Ok();
}

Result<DetectionSet> TagTracker::Track(const cv::Mat& gray8, FrameId frame,
                                       const std::map<TagId, QuadCorners>& predicted) {
  ++stats_.frames;
  const bool scheduled = !have_full_ || frames_since_full_ + 1 >= options_.full_frame_every ||
                         motion_since_full_px_ >= options_.full_frame_after_motion * std::max(gray8.cols, gray8.rows);
  const bool backing_off = full_frames_before_retry_ > 0;
  if (backing_off) {
    --full_frames_before_retry_;
    ++stats_.backed_off;
  }
  const std::map<TagId, QuadCorners> expected = Predict(frame, predicted);
  if (scheduled || backing_off || expected.empty() || gray8.empty()) {
    auto detections = DetectFullFrame(gray8, frame, expected);
    if (detections) Update(*detections);
    return detections;
  }
  ++frames_since_full_;

  PlanSearches(gray8.size(), expected);
  if (Status status = RunSearches(gray8, frame); !status) return status.error();
  std::set<TagId> found_ids;
  DetectionSet result = TakeFound(frame, &found_ids);
  bool lost = false;
  if (Status status = SearchMissed(gray8, frame, expected, found_ids, &result.tags, &lost); !status) {
    return status.error();
  }
  // A tag lost: the prediction failed, or the tag is hidden. Only a
  // full-frame detection tells which, so run one now.
  if (lost) {
    ++stats_.recoveries;
    if (options_.back_off_after_recovery) {
      recoveries_in_a_row_ = std::min(recoveries_in_a_row_ + 1, 16);
      full_frames_before_retry_ = std::min(options_.full_frame_every - 1, (1 << recoveries_in_a_row_) - 1);
    }
    auto detections = DetectFullFrame(gray8, frame, expected);
    if (detections) Update(*detections);
    return detections;
  }
  recoveries_in_a_row_ = 0;
  const auto refine_start = std::chrono::steady_clock::now();
  full_detector_->RefineDetections(gray8, &result.tags);
  stats_.refine_ms += MsSince(refine_start);
  std::sort(result.tags.begin(), result.tags.end(),
            [](const TagDetection& a, const TagDetection& b) { return a.id < b.id; });
  Update(result);
  return result;
}

}  // namespace tagsfm
