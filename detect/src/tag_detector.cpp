// TagDetector on libapriltag 3.3.
#include "tagsfm/detect/tag_detector.h"

#include <algorithm>
#include <cmath>
#include <memory>
#include <optional>
#include <unordered_map>

#include <Eigen/Dense>
#include <apriltag/apriltag.h>
#include <opencv2/aruco.hpp>
#include <opencv2/imgproc.hpp>

#include "apriltag_family.h"
#include "aruco_dictionary.h"
#include "blurred_tag_reader.h"
#include "small_tag_reader.h"
#include "tagsfm/detect/apriltag_worker_pool.h"
#include "tag_detector_workers.h"
#include "tagsfm/detect/corner_refinement.h"
#include "tagsfm/detect/tag_layout.h"

namespace tagsfm {
namespace {

using detail::ArucoDictionaryFor;
using detail::BlurredQuadReading;
using detail::ReadBlurredQuad;
using detail::InsideQuad;
using detail::QuadReading;
using detail::ReadQuad;

// libapriltag puts pixel centres at .5 (pixel i covers [i, i+1)), OpenCV and
// tagsfm at integers (pixel i covers [i-0.5, i+0.5)): subtract half a pixel.
// Measured against exactly rendered tags (tests/detect/corner_accuracy_test):
// no further offset (such as the 0.125 px reported upstream) remains at
// quad_decimate 1 or 2.
constexpr double kAprilTagToOpenCvShift = -0.5;

struct DetectorDeleter {
  void operator()(apriltag_detector_t* detector) const { apriltag_detector_destroy(detector); }
};
struct DetectionsDeleter {
  void operator()(zarray_t* detections) const { apriltag_detections_destroy(detections); }
};

class AprilTagDetector final : public TagDetector {
 public:
  AprilTagDetector(TagDetectorOptions options, detail::FamilyPtr family)
      : TagDetector(std::move(options)), family_(std::move(family)), detector_(apriltag_detector_create()) {
    apriltag_detector_t* td = detector_.get();
    td->nthreads = options_.threads;
    td->quad_decimate = options_.quad_decimate;
    td->quad_sigma = options_.quad_sigma;
    td->refine_edges = options_.refine_edges || options_.refinement == CornerRefinement::kAprilTag;
    td->decode_sharpening = options_.decode_sharpening;
    apriltag_detector_add_family_bits(td, family_.get(), options_.max_hamming);
    StartAprilTagWorkerPool(td);  // libapriltag 3.3's first threaded run races with its threads' start
    if (options_.small_tag_pass) {
      aruco_dictionary_ = ArucoDictionaryFor(options_.family);
      aruco_parameters_ = cv::aruco::DetectorParameters::create();
      aruco_parameters_->minDistanceToBorder = 1;
    }
  }

  ~AprilTagDetector() override {
    // The detector refers to the family: destroy it first.
    detector_.reset();
  }

  int ModulesAcrossCornerSquare() const override { return family_->width_at_border; }

  Result<DetectionSet> Detect(const cv::Mat& gray8, FrameId frame) override {
    DetectionSet result;
    result.frame = frame;
    if (gray8.empty()) return result;
    if (gray8.depth() != CV_8U || gray8.channels() != 1) {
      return MakeError("frame " + std::to_string(frame) + ": tag detection needs an 8-bit single-channel image (got " +
                       std::to_string(gray8.channels()) + " channel(s) of depth " + DepthName(gray8.depth()) + ")");
    }
    if (gray8.dims != 2) return MakeError("frame " + std::to_string(frame) + ": image is not 2-D");
    // No tag fits in fewer pixels than its modules.
    if (gray8.rows < family_->total_width || gray8.cols < family_->total_width) return result;

    // A view of the caller's pixels, row stride included: no copy.
    // libapriltag only reads the input image (it blurs/decimates copies).
    image_u8_t image{gray8.cols, gray8.rows, static_cast<int32_t>(gray8.step[0]), const_cast<uint8_t*>(gray8.data)};
    std::unique_ptr<zarray_t, DetectionsDeleter> detections(apriltag_detector_detect(detector_.get(), &image));
    if (!detections) return MakeError("frame " + std::to_string(frame) + ": libapriltag failed");

    for (int i = 0; i < zarray_size(detections.get()); ++i) {
      apriltag_detection_t* det = nullptr;
      zarray_get(detections.get(), i, &det);
      if (det->hamming > options_.max_hamming || det->decision_margin < options_.min_decision_margin) continue;
      TagDetection tag;
      tag.id = det->id;
      tag.hamming = det->hamming;
      tag.decision_margin = det->decision_margin;
      for (int k = 0; k < 4; ++k) {
        tag.corners[k] = Eigen::Vector2d(det->p[k][0] + kAprilTagToOpenCvShift, det->p[k][1] + kAprilTagToOpenCvShift);
      }
      result.tags.push_back(tag);
    }
    RefineAll(gray8, &result.tags);
    if (options_.small_tag_pass) SmallTagPass(gray8, &result.tags);
    DropTagsCutByTheBorder(gray8.size(), &result.tags);
    std::sort(result.tags.begin(), result.tags.end(),
              [](const TagDetection& a, const TagDetection& b) { return a.id < b.id; });
    return result;
  }

 private:
  static std::string DepthName(int depth) {
    switch (depth) {
      case CV_8U: return "8U";
      case CV_8S: return "8S";
      case CV_16U: return "16U";
      case CV_16S: return "16S";
      case CV_32S: return "32S";
      case CV_32F: return "32F";
      case CV_64F: return "64F";
      default: return std::to_string(depth);
    }
  }

  // Tags are refined independently, on the detector's threads (a pool
  // started once: a tag's refinement is 0.1-1 ms, too short to start threads for).
  void RefineDetections(const cv::Mat& gray8, std::vector<TagDetection>* tags) override {
    RefineAll(gray8, tags);
    DropTagsCutByTheBorder(gray8.size(), tags);
  }

  void RefineAll(const cv::Mat& gray8, std::vector<TagDetection>* tags) {
    if (options_.refinement == CornerRefinement::kNone || options_.refinement == CornerRefinement::kAprilTag) return;
    if (tags->empty() || gray8.empty()) return;
    for (const TagDetection& tag : *tags) Layout(tag.id);  // fill the cache before threads read it
    workers_.Run(static_cast<int>(tags->size()), [&](int i, int) { (void)Refine(gray8, &(*tags)[i]); });
  }

  // Cut by the image border: their corners cannot be measured.
  void DropTagsCutByTheBorder(const cv::Size& image, std::vector<TagDetection>* tags) const {
    if (!options_.drop_tags_cut_by_border) return;
    tags->erase(std::remove_if(tags->begin(), tags->end(),
                               [&](const TagDetection& t) {
                                 return !ClearOfImageBorder(t.corners, image.width, image.height);
                               }),
                tags->end());
  }

  // A failed refinement keeps libapriltag's corners: a tag is never lost to
  // it. False if it failed.
  bool Refine(const cv::Mat& gray8, TagDetection* tag) const {
    tag->corner_covariance.fill(Eigen::Matrix2d::Zero());  // known only from an edge fit that succeeds
    switch (options_.refinement) {
      case CornerRefinement::kNone:
      case CornerRefinement::kAprilTag:
        return true;
      case CornerRefinement::kCornerSubPix:
        return RefineCornersBySubPix(gray8, family_->width_at_border, &tag->corners);
      case CornerRefinement::kEdgeLineFit:
        // With the lens first; where that fit declines (it does on a tag of
        // the wide-lens test image whose libapriltag corners are 1.1 px
        // off), the fit without it still beats keeping libapriltag's
        // corners (there: 0.02 px from the truth instead of 1.13).
        if (options_.camera && RefineCornersByEdgeLines(gray8, Layout(tag->id), &tag->corners, &*options_.camera,
                                                        &tag->corner_covariance)) {
          return true;
        }
        return RefineCornersByEdgeLines(gray8, Layout(tag->id), &tag->corners, nullptr, &tag->corner_covariance);
    }
    return false;
  }

  // Tags read from aruco's candidates whose ids `tags` lacks and whose
  // centres lie outside its tags. First the module-centre reading (ReadQuad):
  // a first reading with up to 2 bit errors names the id, the corners are
  // refined for that id, then a second reading on the refined corners must
  // give that id exactly, in the same corner order, with the margin. Where
  // that fails, the blur-model reading (ReadBlurredQuad), which fits the
  // corners itself: an exact code that the model explains.
  void SmallTagPass(const cv::Mat& gray8, std::vector<TagDetection>* tags) {
    std::vector<std::vector<cv::Point2f>> accepted, rejected;
    std::vector<int> aruco_ids;
    cv::aruco::detectMarkers(gray8, aruco_dictionary_, accepted, aruco_ids, aruco_parameters_, rejected);
    accepted.insert(accepted.end(), rejected.begin(), rejected.end());
    const size_t first_pass = tags->size();
    const auto known = [&](TagId id) {
      return std::any_of(tags->begin(), tags->begin() + static_cast<std::ptrdiff_t>(first_pass),
                         [id](const TagDetection& t) { return t.id == id; });
    };
    for (const std::vector<cv::Point2f>& marker : accepted) {
      if (marker.size() != 4) continue;
      QuadCorners quad;
      Eigen::Vector2d centre = Eigen::Vector2d::Zero();
      for (int k = 0; k < 4; ++k) {
        quad[k] = Eigen::Vector2d(marker[k].x, marker[k].y);
        centre += quad[k] / 4.0;
      }
      bool covered = false;
      for (size_t i = 0; i < first_pass && !covered; ++i) covered = InsideQuad((*tags)[i].corners, centre);
      if (covered) continue;
      std::optional<TagDetection> tag = ReadByModuleCentres(gray8, quad);
      if (!tag) tag = ReadByBlurModel(gray8, quad);
      if (!tag || known(tag->id)) continue;
      // One tag per id: the better reading.
      auto it = std::find_if(tags->begin() + static_cast<std::ptrdiff_t>(first_pass), tags->end(),
                             [&](const TagDetection& t) { return t.id == tag->id; });
      if (it == tags->end()) {
        tags->push_back(*tag);
      } else if (tag->decision_margin > it->decision_margin) {
        *it = *tag;
      }
    }
  }

  std::optional<TagDetection> ReadByModuleCentres(const cv::Mat& gray8, const QuadCorners& quad) const {
    const std::optional<QuadReading> guess = ReadQuad(gray8, family_.get(), quad, 2, kSmallTagMinContrast);
    if (!guess) return std::nullopt;
    TagDetection tag;
    tag.id = guess->id;
    tag.corners = guess->corners;
    Layout(tag.id);
    // aruco's corners (contour pixels) are up to ~1.5 px off: a tag whose
    // refinement fails is dropped.
    if (options_.refinement != CornerRefinement::kNone && !Refine(gray8, &tag)) return std::nullopt;
    const std::optional<QuadReading> check = ReadQuad(gray8, family_.get(), tag.corners, 0, kSmallTagMinContrast);
    if (!check || check->id != tag.id || check->margin < options_.small_tag_min_margin) return std::nullopt;
    for (int k = 0; k < 4; ++k) {
      if ((check->corners[k] - tag.corners[k]).norm() >= 1e-9) return std::nullopt;  // another corner order
    }
    tag.hamming = 0;
    tag.decision_margin = check->margin * check->contrast;  // grey levels, like libapriltag's
    return tag;
  }

  // The corners from the model fit, then refined like any tag's if the
  // refined corners still read the code exactly (the edge-line fit is the
  // measured-accurate one; on a glared or badly blurred tag it can slide).
  std::optional<TagDetection> ReadByBlurModel(const cv::Mat& gray8, const QuadCorners& quad) const {
    const std::optional<BlurredQuadReading> reading =
        ReadBlurredQuad(gray8, family_.get(), quad, 0, kSmallTagMinContrast);
    if (!reading || reading->residual > kMaxBlurModelResidual) return std::nullopt;
    TagDetection tag;
    tag.id = reading->reading.id;
    tag.corners = reading->reading.corners;
    tag.hamming = 0;
    tag.decision_margin = reading->reading.margin * reading->reading.contrast;
    if (options_.refinement == CornerRefinement::kNone) return tag;
    Layout(tag.id);
    TagDetection refined = tag;
    if (!Refine(gray8, &refined)) return tag;
    const std::optional<BlurredQuadReading> again =
        ReadBlurredQuad(gray8, family_.get(), refined.corners, 0, kSmallTagMinContrast);
    if (!again || again->reading.id != tag.id || again->residual > kMaxBlurModelResidual) return tag;
    for (int k = 0; k < 4; ++k) {
      if ((again->reading.corners[k] - refined.corners[k]).norm() > 2.0) return tag;  // another corner order
    }
    return refined;
  }
  // RMS misfit of the code's model over the contrast: ~0.03-0.15 on the
  // swatbotics tags (0.15: one in a lamp's glare).
  static constexpr double kMaxBlurModelResidual = 0.25;
  static constexpr double kSmallTagMinContrast = 10.0;  // grey levels, white ring over black border

  // Not thread-safe on a miss: RefineAll fills the cache first.
  const TagLayout& Layout(TagId id) const {
    auto it = layouts_.find(id);
    if (it == layouts_.end()) it = layouts_.emplace(id, detail::LayoutOf(family_.get(), id)).first;
    return it->second;
  }

  detail::FamilyPtr family_;
  mutable std::unordered_map<TagId, TagLayout> layouts_;  // per id, built on first sight
  std::unique_ptr<apriltag_detector_t, DetectorDeleter> detector_;
  detail::DetectionWorkers workers_{options_.threads};
  cv::Ptr<cv::aruco::Dictionary> aruco_dictionary_;
  cv::Ptr<cv::aruco::DetectorParameters> aruco_parameters_;
};

}  // namespace

Status SmallTagPassCanRead(const std::string& family_name) {
  Result<detail::FamilyPtr> family = detail::CreateAprilTagFamily(family_name);
  if (!family) return family.error();
  if (!ArucoDictionaryFor(family_name)) {
    return MakeError("small_tag_pass: OpenCV aruco has no dictionary for family " + family_name +
                     " (tag36h11, tag36h10 and tag25h9 have one)");
  }
  // Reading arbitrary quads needs a code that few patterns match by
  // chance: of 2^nbits patterns, 8 ncodes (corner orders) are codes.
  const double chance = 8.0 * (*family)->ncodes / std::ldexp(1.0, static_cast<int>((*family)->nbits));
  if (chance > 1e-4) {
    return MakeError("small_tag_pass: family " + family_name + " is too weak to read tags from arbitrary quads (" +
                     std::to_string((*family)->nbits) + " bits: about 1 quad in " +
                     std::to_string(static_cast<int>(1.0 / chance)) + " reads as a code)");
  }
  return Status::Ok();
}

Result<std::unique_ptr<TagDetector>> TagDetector::Create(const TagDetectorOptions& options) {
  if (Status status = options.Check(); !status) return status.error();
  Result<detail::FamilyPtr> family = detail::CreateAprilTagFamily(options.family);
  if (!family) return family.error();
  if (options.small_tag_pass) {
    if (Status status = SmallTagPassCanRead(options.family); !status) return status.error();
  }
  std::unique_ptr<TagDetector> detector = std::make_unique<AprilTagDetector>(options, std::move(*family));
  return detector;
}

}  // namespace tagsfm
