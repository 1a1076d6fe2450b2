#pragma once
// Corner errors of detections against exactly known corners.
#include <algorithm>
#include <cmath>
#include <map>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "tagsfm/detect/corner_refinement.h"
#include "tagsfm/detect/synthetic_tags.h"
#include "tagsfm/detect/tag_detection.h"
#include "tagsfm/detect/tag_layout.h"

namespace tagsfm::testing {

struct CornerStats {
  int truth_tags = 0;
  int found_tags = 0;
  int wrong_ids = 0;
  std::vector<double> errors;  // |detected - true| per corner, px
  std::vector<double> outward;  // signed offset along the outward diagonal per corner, px
  double bias = 0.0;           // mean signed offset along the outward diagonal, px
  double mean_x = 0.0;         // mean offset in x and y, px
  double mean_y = 0.0;

  double Percentile(double q) const {
    if (errors.empty()) return NAN;
    std::vector<double> sorted = errors;
    std::sort(sorted.begin(), sorted.end());
    const size_t i = std::min(sorted.size() - 1, static_cast<size_t>(q * (sorted.size() - 1) + 0.5));
    return sorted[i];
  }
  double Median() const { return Percentile(0.5); }
  // Bias over the corners within `max_error` px of the truth: the few gross
  // errors (an occluded tag, a refinement that declined and kept
  // libapriltag's corner) would otherwise dominate a mean of 0.001 px.
  double InlierBias(double max_error = 0.5) const {
    double sum = 0.0;
    int count = 0;
    for (size_t i = 0; i < errors.size(); ++i) {
      if (errors[i] > max_error) continue;
      sum += outward[i];
      ++count;
    }
    return count > 0 ? sum / count : NAN;
  }
  int CountAbove(double error) const {
    return static_cast<int>(std::count_if(errors.begin(), errors.end(), [&](double e) { return e > error; }));
  }
  double Max() const { return errors.empty() ? NAN : *std::max_element(errors.begin(), errors.end()); }
  std::string Summary() const {
    char text[320];
    std::snprintf(text, sizeof(text),
                  "found %d/%d wrong %d median %.4f p95 %.4f max %.4f bias %+.4f (%+.4f over %zu corners within 0.5 px) "
                  "mean (%+.4f, %+.4f)",
                  found_tags, truth_tags, wrong_ids, Median(), Percentile(0.95), Max(), bias, InlierBias(),
                  errors.size() - CountAbove(0.5), mean_x, mean_y);
    return text;
  }
};

// Accumulates one frame's detections into `stats`.
inline void AccumulateCornerStats(const std::vector<PlacedTag>& truth, const DetectionSet& detections,
                                  CornerStats* stats) {
  std::map<TagId, const PlacedTag*> by_id;
  for (const PlacedTag& t : truth) by_id[t.id] = &t;
  stats->truth_tags += static_cast<int>(truth.size());
  double bias_sum = stats->bias * stats->errors.size();
  double x_sum = stats->mean_x * stats->errors.size();
  double y_sum = stats->mean_y * stats->errors.size();
  for (const TagDetection& det : detections.tags) {
    const auto it = by_id.find(det.id);
    if (it == by_id.end()) {
      ++stats->wrong_ids;
      continue;
    }
    ++stats->found_tags;
    const QuadCorners& true_corners = it->second->corners;
    const Eigen::Vector2d center = 0.25 * (true_corners[0] + true_corners[1] + true_corners[2] + true_corners[3]);
    for (int k = 0; k < 4; ++k) {
      const Eigen::Vector2d offset = det.corners[k] - true_corners[k];
      stats->errors.push_back(offset.norm());
      stats->outward.push_back(offset.dot((true_corners[k] - center).normalized()));
      bias_sum += stats->outward.back();
      x_sum += offset.x();
      y_sum += offset.y();
    }
  }
  if (!stats->errors.empty()) {
    stats->bias = bias_sum / stats->errors.size();
    stats->mean_x = x_sum / stats->errors.size();
    stats->mean_y = y_sum / stats->errors.size();
  }
}

// The edge fit alone: each true tag36h11 tag's corners moved by ~0.2 px
// (Gaussian per coordinate, drawn from `rng`) and refined, through
// `camera`'s lens when given. Tags the fit declines are left out.
inline DetectionSet FitFromMovedTruth(const cv::Mat& image, const std::vector<PlacedTag>& truth, std::mt19937& rng,
                                      const CameraModel* camera = nullptr) {
  std::normal_distribution<double> start_error(0.0, 0.2);
  DetectionSet fitted;
  for (const PlacedTag& tag : truth) {
    const Result<TagLayout> layout = MakeTagLayout("tag36h11", tag.id);
    EXPECT_TRUE(layout.has_value()) << "tag " << tag.id;
    if (!layout) continue;
    TagDetection t;
    t.id = tag.id;
    t.corners = tag.corners;
    for (Eigen::Vector2d& c : t.corners) c += Eigen::Vector2d(start_error(rng), start_error(rng));
    if (RefineCornersByEdgeLines(image, *layout, &t.corners, camera)) fitted.tags.push_back(t);
  }
  return fitted;
}

}  // namespace tagsfm::testing
