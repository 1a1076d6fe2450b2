// Tags at the image border: a tag the border cuts is reported with a corner
// where it cannot be measured (one of a rendered 1280x720 walk whose corner
// lay 1.1 px beyond the last row: 1.7 px off, and 3.4 mm off in the map).
// The detector drops every tag with a corner within 3 px of the border and
// keeps the others.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <set>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "tagsfm/detect/synthetic_tags.h"
#include "tagsfm/detect/tag_detector.h"

namespace tagsfm {
namespace {

constexpr int kWidth = 960, kHeight = 960;

// Tags of about 24 px (3 px modules), tilted 25-35 degrees and turned 20
// degrees in the image (so that one corner leads), along the bottom and
// right borders: their outermost corner from 6 px inside the image to 1.5 px
// beyond it, in steps of 0.5 px.
std::vector<PlacedTag> TagsAlongTwoBorders() {
  std::vector<PlacedTag> tags;
  int id = 0;
  for (int border = 0; border < 2; ++border) {
    for (int step = 0; step < 16; ++step) {
      const double beyond = -6.0 + 0.5 * step;  // outermost corner's distance past the border, px
      const double along = 60.0 + 55.0 * step;
      const Eigen::Matrix3d rotation =
          (Eigen::AngleAxisd(0.35, Eigen::Vector3d::UnitZ()) *
           Eigen::AngleAxisd(0.45 + 0.02 * step, Eigen::Vector3d::UnitX()) *
           Eigen::AngleAxisd(0.15 * (border == 0 ? 1 : -1), Eigen::Vector3d::UnitY()))
              .toRotationMatrix();
      PlacedTag tag = TagSeenFromOneMetre(id++, border == 0 ? along : kWidth / 2.0,
                                          border == 0 ? kHeight / 2.0 : along, 24.0, rotation);
      // Shift it so that its outermost corner lies `beyond` past the border.
      double outermost = -1e9;
      for (const Eigen::Vector2d& c : tag.corners) outermost = std::max(outermost, border == 0 ? c.y() : c.x());
      const double edge = border == 0 ? kHeight - 1 : kWidth - 1;
      const Eigen::Vector2d shift = border == 0 ? Eigen::Vector2d(0, edge + beyond - outermost)
                                                : Eigen::Vector2d(edge + beyond - outermost, 0);
      for (Eigen::Vector2d& c : tag.corners) c += shift;
      tags.push_back(tag);
    }
  }
  return tags;
}

double WorstCornerError(const TagDetection& found, const PlacedTag& truth) {
  double worst = 0;
  for (int k = 0; k < 4; ++k) worst = std::max(worst, (found.corners[k] - truth.corners[k]).norm());
  return worst;
}

struct BorderRun {
  std::set<TagId> clear_found;  // the tags clear of the border (by the rule, and 0.7 px more) found
  int clear_tags = 0;
  int reported = 0;
  double worst_reported_px = 0;  // over every reported tag's corners
};

// The scene over texture at blur 0.5 + 0.2 * seed px, noise 2 (empty on an error).
cv::Mat Render(const std::vector<PlacedTag>& truth, int seed) {
  TagRenderOptions render;
  render.blur_sigma_px = 0.5 + 0.2 * seed;
  render.noise_sigma = 2.0;
  render.texture_contrast = 40.0;
  render.seed = static_cast<std::uint64_t>(seed);
  auto image = RenderTags("tag36h11", kWidth, kHeight, truth, render);
  EXPECT_TRUE(image.has_value());
  return image ? *image : cv::Mat();
}

BorderRun Detect(const cv::Mat& image, const std::vector<PlacedTag>& truth, bool drop_tags_cut_by_border) {
  TagDetectorOptions options;
  options.drop_tags_cut_by_border = drop_tags_cut_by_border;
  auto detector = TagDetector::Create(options);
  EXPECT_TRUE(detector.has_value());
  BorderRun run;
  if (image.empty() || !detector) return run;
  auto found = (*detector)->Detect(image, 0);
  EXPECT_TRUE(found.has_value());
  if (!found) return run;
  for (const PlacedTag& tag : truth) {
    // Clear by 0.7 px more than the rule asks: kept whatever the noise.
    std::array<Eigen::Vector2d, 4> grown = tag.corners;
    const Eigen::Vector2d centre = 0.25 * (grown[0] + grown[1] + grown[2] + grown[3]);
    for (Eigen::Vector2d& c : grown) c += (c - centre).normalized() * 0.7;
    if (!ClearOfImageBorder(grown, kWidth, kHeight)) continue;
    ++run.clear_tags;
    for (const TagDetection& d : found->tags) {
      if (d.id == tag.id) run.clear_found.insert(d.id);
    }
  }
  for (const TagDetection& d : found->tags) {
    ++run.reported;
    run.worst_reported_px = std::max(run.worst_reported_px, WorstCornerError(d, truth.at(static_cast<size_t>(d.id))));
  }
  return run;
}

TEST(ImageBorder, TagsCutByTheBorderAreDroppedAndTagsClearOfItKept) {
  const std::vector<PlacedTag> truth = TagsAlongTwoBorders();
  double worst_without_rule = 0;
  for (int seed = 1; seed <= 3; ++seed) {
    const cv::Mat image = Render(truth, seed);
    const BorderRun all = Detect(image, truth, false);
    const BorderRun kept = Detect(image, truth, true);
    worst_without_rule = std::max(worst_without_rule, all.worst_reported_px);
    EXPECT_GT(all.reported, kept.reported) << "seed " << seed;
    // With the rule every reported corner is measured (0.3 px: several times
    // the edge fit's error on whole 24 px tags at noise 2, 0.02-0.1 px), and
    // every tag clear of the border that is found without it is kept.
    EXPECT_LT(kept.worst_reported_px, 0.3) << "seed " << seed;
    EXPECT_GE(all.clear_found.size(), 8u) << "seed " << seed;
    EXPECT_EQ(kept.clear_found, all.clear_found) << "seed " << seed;
    std::printf("seed %d: %d tags reported without the rule (worst corner %.2f px), %d with it (%.3f px); "
                "%zu of %d tags clear of the border found\n",
                seed, all.reported, all.worst_reported_px, kept.reported, kept.worst_reported_px,
                kept.clear_found.size(), kept.clear_tags);
  }
  // Without the rule a cut tag is reported with a corner well off: what the
  // rule is for (seed 1 has one, 1.9 px off, reported 1.3 px inside the border).
  EXPECT_GT(worst_without_rule, 0.5);
}

TEST(ImageBorder, EveryCornerThreePixelsInsideTheOuterPixelCentres) {
  auto square = [](double x0, double y0) {
    return std::array<Eigen::Vector2d, 4>{Eigen::Vector2d(x0, y0), Eigen::Vector2d(x0 + 24, y0),
                                          Eigen::Vector2d(x0 + 24, y0 + 24), Eigen::Vector2d(x0, y0 + 24)};
  };
  EXPECT_TRUE(ClearOfImageBorder(square(3.0, 3.0), 100, 80));
  EXPECT_FALSE(ClearOfImageBorder(square(2.9, 30), 100, 80));
  EXPECT_FALSE(ClearOfImageBorder(square(30, 2.9), 100, 80));
  EXPECT_TRUE(ClearOfImageBorder(square(72.0, 52.0), 100, 80));  // 99 - 3 - 24, 79 - 3 - 24
  EXPECT_FALSE(ClearOfImageBorder(square(72.1, 30), 100, 80));
  EXPECT_FALSE(ClearOfImageBorder(square(30, 52.1), 100, 80));
}

}  // namespace
}  // namespace tagsfm
