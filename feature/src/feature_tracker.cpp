#include "tagsfm/feature/feature_tracker.h"

#include <opencv2/calib3d.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include "tagsfm/feature/tag_mask.h"

namespace tagsfm {

Status FeatureTrackerOptions::Check() const {
  if (max_features < 10) return MakeError("features.max_features must be >= 10");
  if (!(ratio > 0 && ratio < 1)) return MakeError("features.ratio must be in (0, 1)");
  if (!(epipolar_px > 0)) return MakeError("features.epipolar_px must be > 0");
  if (min_matches < 8) return MakeError("features.min_matches must be >= 8 (the fundamental matrix needs 8)");
  if (!(tag_margin >= 0)) return MakeError("features.tag_margin must be >= 0");
  if (!(image_scale > 0.1 && image_scale <= 1)) return MakeError("features.image_scale must be in (0.1, 1]");
  return Status::Ok();
}

struct FeatureTracker::State {
  FeatureTrackerOptions options;
  cv::Ptr<cv::SIFT> sift;
  cv::BFMatcher matcher{cv::NORM_L2};
  // The previous call's features: positions, descriptors, tracks.
  std::vector<cv::Point2f> points;
  cv::Mat descriptors;
  std::vector<TrackId> tracks;
  TrackId next_track = 0;
};

FeatureTracker::FeatureTracker(std::unique_ptr<State> state) : state_(std::move(state)) {}
FeatureTracker::~FeatureTracker() = default;

Result<std::unique_ptr<FeatureTracker>> FeatureTracker::Create(const FeatureTrackerOptions& options) {
  if (Status s = options.Check(); !s) return s.error();
  auto state = std::make_unique<State>();
  state->options = options;
  state->sift = cv::SIFT::create(options.max_features);
  return std::unique_ptr<FeatureTracker>(new FeatureTracker(std::move(state)));
}

Result<FeatureSet> FeatureTracker::Track(const cv::Mat& gray, const cv::Mat& colour, const DetectionSet& tags) {
  if (gray.empty() || gray.type() != CV_8UC1) return MakeError("frame " + std::to_string(tags.frame) + ": features need an 8-bit grey image");
  State& s = *state_;
  std::vector<cv::KeyPoint> keypoints;
  cv::Mat descriptors;
  const double scale = s.options.image_scale;
  if (scale < 1.0) {
    cv::Mat small, mask;
    cv::resize(gray, small, cv::Size(), scale, scale, cv::INTER_AREA);
    cv::resize(MaskOutsideTags(gray.size(), tags, s.options.tag_margin), mask, small.size(), 0, 0, cv::INTER_NEAREST);
    s.sift->detectAndCompute(small, mask, keypoints, descriptors);
  } else {
    s.sift->detectAndCompute(gray, MaskOutsideTags(gray.size(), tags, s.options.tag_margin), keypoints, descriptors);
  }

  // OpenCV 4.6's SIFT doubles the image first (pixel-centre aligned) but
  // halves the keypoints' coordinates as if corner aligned: every keypoint
  // comes out +0.25 px in x and y. Measured and pinned by
  // FeatureTracker.TracksFollowAKnownHomographyWithoutOffset (a zoom turns a
  // constant offset into a mean residual); a 0.25 px shift would bias every
  // feature point by about depth * 0.25 / f.
  constexpr float kSiftOffsetPx = 0.25f;
  std::vector<cv::Point2f> points;
  points.reserve(keypoints.size());
  // Back to full-size pixels, pixel centres at integers at both scales.
  for (const cv::KeyPoint& k : keypoints) {
    points.emplace_back(static_cast<float>((k.pt.x - kSiftOffsetPx + 0.5) / scale - 0.5),
                        static_cast<float>((k.pt.y - kSiftOffsetPx + 0.5) / scale - 0.5));
  }
  std::vector<TrackId> tracks(keypoints.size(), -1);

  // Candidate matches: ratio test and mutual best match.
  FeatureSet set;
  set.frame = tags.frame;
  if (!s.descriptors.empty() && !descriptors.empty() && s.descriptors.rows >= 2 && descriptors.rows >= 2) {
    std::vector<std::vector<cv::DMatch>> forward;
    std::vector<cv::DMatch> backward;
    s.matcher.knnMatch(descriptors, s.descriptors, forward, 2);
    s.matcher.match(s.descriptors, descriptors, backward);
    std::vector<int> current, previous;
    std::vector<cv::Point2f> from, to;
    for (const auto& m : forward) {
      if (m.size() < 2 || m[0].distance >= s.options.ratio * m[1].distance) continue;
      if (backward[static_cast<size_t>(m[0].trainIdx)].trainIdx != m[0].queryIdx) continue;
      current.push_back(m[0].queryIdx);
      previous.push_back(m[0].trainIdx);
      to.push_back(points[static_cast<size_t>(m[0].queryIdx)]);
      from.push_back(s.points[static_cast<size_t>(m[0].trainIdx)]);
    }
    // Epipolar check: only matches consistent with one rigid motion continue.
    if (static_cast<int>(current.size()) >= s.options.min_matches) {
      std::vector<uchar> inlier;
      const cv::Mat f = cv::findFundamentalMat(from, to, cv::FM_RANSAC, s.options.epipolar_px, 0.999, inlier);
      if (!f.empty() && static_cast<int>(std::count(inlier.begin(), inlier.end(), 1)) >= s.options.min_matches) {
        for (size_t i = 0; i < current.size(); ++i) {
          if (inlier[i]) {
            tracks[static_cast<size_t>(current[i])] = s.tracks[static_cast<size_t>(previous[i])];
            ++set.continued;
          }
        }
      }
    }
  }

  set.features.reserve(keypoints.size());
  for (size_t i = 0; i < keypoints.size(); ++i) {
    if (tracks[i] < 0) tracks[i] = s.next_track++;
    FeatureObservation f;
    f.track = tracks[i];
    f.pixel = Eigen::Vector2d(points[i].x, points[i].y);
    const cv::Point p(std::clamp(cvRound(points[i].x), 0, gray.cols - 1), std::clamp(cvRound(points[i].y), 0, gray.rows - 1));
    if (colour.type() == CV_8UC3 && colour.size() == gray.size()) {
      const cv::Vec3b bgr = colour.at<cv::Vec3b>(p);
      f.rgb = {bgr[2], bgr[1], bgr[0]};
    } else {
      const std::uint8_t g = gray.at<std::uint8_t>(p);
      f.rgb = {g, g, g};
    }
    set.features.push_back(f);
  }
  s.points = std::move(points);
  s.descriptors = std::move(descriptors);
  s.tracks = std::move(tracks);
  return set;
}

}  // namespace tagsfm
