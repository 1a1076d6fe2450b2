#include "tagsfm/feature/guided_matcher.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>

namespace tagsfm {

DepthRange DepthRange::Around(double depth_m, double factor) { return DepthRange{depth_m / factor, depth_m * factor}; }

double DepthRange::Typical() const { return std::sqrt(near_m * far_m); }

Status DepthRange::Check() const {
  if (!(near_m > 0 && std::isfinite(far_m) && far_m > near_m)) {
    return MakeError("depth range must have 0 < near < far (got " + std::to_string(near_m) + ", " + std::to_string(far_m) + ")");
  }
  return Status::Ok();
}

Status GuidedMatcherOptions::Check() const {
  if (!(epipolar_px > 0)) return MakeError("matcher.epipolar_px must be > 0");
  if (!(ratio > 0 && ratio <= 1)) return MakeError("matcher.ratio must be in (0, 1]");
  if (!(max_descriptor_distance > 0 && max_descriptor_distance <= 2)) return MakeError("matcher.max_descriptor_distance must be in (0, 2]");
  if (grid_cell_px < 2) return MakeError("matcher.grid_cell_px must be >= 2");
  return Status::Ok();
}

Result<PosedKeyframe> MakePosedKeyframe(KeyframeFeatures features, const Rigid3d& cam_from_world, const DepthRange& depth,
                                        const CameraModel& camera) {
  if (Status s = features.Check(); !s) return s.error();
  if (Status s = depth.Check(); !s) return MakeError("frame " + std::to_string(features.frame) + ": " + s.error().message);
  PosedKeyframe k;
  k.undistorted = camera.PixelsToNormalized(features.pixels);
  for (Eigen::Vector2d& p : k.undistorted) p = Eigen::Vector2d(camera.fx * p.x() + camera.cx, camera.fy * p.y() + camera.cy);
  k.features = std::move(features);
  k.cam_from_world = cam_from_world;
  k.depth = depth;
  return k;
}

namespace {

// The second keyframe's features bucketed in square cells (CSR layout).
class FeatureGrid {
 public:
  FeatureGrid(const std::vector<Eigen::Vector2d>& points, double cell) : cell_(cell) {
    lo_ = Eigen::Vector2d::Constant(std::numeric_limits<double>::max());
    Eigen::Vector2d hi = -lo_;
    for (const Eigen::Vector2d& p : points) {
      lo_ = lo_.cwiseMin(p);
      hi = hi.cwiseMax(p);
    }
    if (points.empty()) lo_ = hi = Eigen::Vector2d::Zero();
    hi_ = hi;
    cols_ = static_cast<int>((hi.x() - lo_.x()) / cell) + 1;
    rows_ = static_cast<int>((hi.y() - lo_.y()) / cell) + 1;
    start_.assign(static_cast<size_t>(cols_ * rows_) + 1, 0);
    std::vector<int> cell_of(points.size());
    for (size_t i = 0; i < points.size(); ++i) {
      cell_of[i] = Cell(points[i]);
      ++start_[static_cast<size_t>(cell_of[i]) + 1];
    }
    for (size_t c = 1; c < start_.size(); ++c) start_[c] += start_[c - 1];
    items_.resize(points.size());
    std::vector<int> fill(start_.begin(), start_.end() - 1);
    for (size_t i = 0; i < points.size(); ++i) items_[static_cast<size_t>(fill[static_cast<size_t>(cell_of[i])]++)] = static_cast<int>(i);
  }

  const Eigen::Vector2d& lo() const { return lo_; }
  const Eigen::Vector2d& hi() const { return hi_; }

  // Calls visit(item, slot) for the items of every cell that the band of
  // half-width w round the segment a-b touches: a superset of the items
  // within w of the segment, found row of cells by row. A row's cells are
  // consecutive slots, so each row is one run through memory. Slots number
  // the items cell by cell (row-major).
  template <typename Visit>
  void ForItemsNearSegment(const Eigen::Vector2d& a, const Eigen::Vector2d& b, double w, Visit&& visit) const {
    const Eigen::Vector2d d = b - a;
    const int first_row = std::max(0, static_cast<int>(std::floor((std::min(a.y(), b.y()) - w - lo_.y()) / cell_)));
    const int last_row = std::min(rows_ - 1, static_cast<int>(std::floor((std::max(a.y(), b.y()) + w - lo_.y()) / cell_)));
    for (int row = first_row; row <= last_row; ++row) {
      // The part of the segment within w (in y) of this row: a point of the
      // row within w of the segment lies within w (in x) of that part.
      const double y0 = lo_.y() + row * cell_ - w, y1 = lo_.y() + (row + 1) * cell_ + w;
      double t0 = 0, t1 = 1;
      if (d.y() != 0) {
        const double ta = (y0 - a.y()) / d.y(), tb = (y1 - a.y()) / d.y();
        t0 = std::max(t0, std::min(ta, tb));
        t1 = std::min(t1, std::max(ta, tb));
        if (t0 > t1) continue;
      } else if (a.y() < y0 || a.y() > y1) {
        continue;
      }
      const double xa = a.x() + t0 * d.x(), xb = a.x() + t1 * d.x();
      const int c0 = std::max(0, static_cast<int>(std::floor((std::min(xa, xb) - w - lo_.x()) / cell_)));
      const int c1 = std::min(cols_ - 1, static_cast<int>(std::floor((std::max(xa, xb) + w - lo_.x()) / cell_)));
      if (c0 > c1) continue;
      const int end = start_[static_cast<size_t>(row * cols_ + c1 + 1)];
      for (int k = start_[static_cast<size_t>(row * cols_ + c0)]; k < end; ++k) visit(items_[static_cast<size_t>(k)], k);
    }
  }
  const std::vector<int>& ItemsBySlot() const { return items_; }

 private:
  int Cell(const Eigen::Vector2d& p) const {
    const int x = std::clamp(static_cast<int>((p.x() - lo_.x()) / cell_), 0, cols_ - 1);
    const int y = std::clamp(static_cast<int>((p.y() - lo_.y()) / cell_), 0, rows_ - 1);
    return y * cols_ + x;
  }

  double cell_;
  Eigen::Vector2d lo_, hi_;
  int cols_ = 1, rows_ = 1;
  std::vector<int> start_, items_;
};

// Clips the segment a-b to the box [lo, hi] (Liang-Barsky); false if it
// misses the box.
bool ClipSegment(const Eigen::Vector2d& lo, const Eigen::Vector2d& hi, Eigen::Vector2d* a, Eigen::Vector2d* b) {
  double t0 = 0, t1 = 1;
  const Eigen::Vector2d d = *b - *a;
  for (int axis = 0; axis < 2; ++axis) {
    const double p[2] = {-d[axis], d[axis]};
    const double q[2] = {(*a)[axis] - lo[axis], hi[axis] - (*a)[axis]};
    for (int k = 0; k < 2; ++k) {
      if (p[k] == 0) {
        if (q[k] < 0) return false;
        continue;
      }
      const double r = q[k] / p[k];
      if (p[k] < 0) t0 = std::max(t0, r);
      else t1 = std::min(t1, r);
    }
  }
  if (t0 > t1) return false;
  const Eigen::Vector2d start = *a + t0 * d;
  *b = *a + t1 * d;
  *a = start;
  return true;
}

// A segment a-b with what the distance test of each candidate needs worked
// out once: that test is the matcher's inner loop (no square root: about
// a sixth of the matching time went to sqrtsd).
struct Segment {
  Segment(const Eigen::Vector2d& a, const Eigen::Vector2d& b) : a(a), d(b - a) {
    const double length2 = d.squaredNorm();
    inverse_length2 = length2 > 0 ? 1.0 / length2 : 0.0;
  }
  double SquaredDistance(const Eigen::Vector2d& p) const {
    const double t = std::clamp((p - a).dot(d) * inverse_length2, 0.0, 1.0);
    return (p - (a + t * d)).squaredNorm();
  }
  Eigen::Vector2d a, d;
  double inverse_length2;
};

// Squared distance of two byte descriptors, in quanta: summed in integers,
// which the compiler vectorises sixteen bytes at a time. Candidates are
// ranked by it; the square root only for the matches.
std::int32_t SquaredDescriptorDistance(const std::uint8_t* a, const std::uint8_t* b) {
  std::int32_t sum = 0;
  for (int k = 0; k < 128; ++k) {
    const std::int32_t d = static_cast<std::int32_t>(a[k]) - static_cast<std::int32_t>(b[k]);
    sum += d * d;
  }
  return sum;
}

struct BestTwo {
  int best = -1;
  std::int32_t d1 = std::numeric_limits<std::int32_t>::max();  // squared, quanta
  std::int32_t d2 = std::numeric_limits<std::int32_t>::max();

  void Offer(int index, std::int32_t d) {
    if (d < d1) {
      d2 = d1;
      d1 = d;
      best = index;
    } else if (d < d2) {
      d2 = d;
    }
  }
  // Lowe's ratio and the distance limit, on the squares.
  bool Passes(double ratio, double max_distance) const {
    const double max_squared = max_distance * max_distance * kDescriptorQuantum * kDescriptorQuantum;
    return best >= 0 && d1 <= max_squared && d1 < ratio * ratio * static_cast<double>(d2);
  }
};

}  // namespace

GuidedMatches MatchGuided(const PosedKeyframe& first, const PosedKeyframe& second, const CameraModel& camera,
                          const GuidedMatcherOptions& options) {
  GuidedMatches out;
  const int n1 = first.features.size(), n2 = second.features.size();
  if (n1 == 0 || n2 == 0) return out;
  const Rigid3d second_from_first = second.cam_from_world * first.cam_from_world.Inverse();
  const Eigen::Matrix3d r = second_from_first.RotationMatrix();
  const Eigen::Vector3d t = second_from_first.translation;
  const double band = options.epipolar_px;
  const double cell = options.grid_cell_px;
  const FeatureGrid grid(second.undistorted, cell);
  const Eigen::Vector2d lo = grid.lo() - Eigen::Vector2d::Constant(band), hi = grid.hi() + Eigen::Vector2d::Constant(band);
  const double min_z = 1e-3 * first.depth.near_m;

  // The second keyframe's descriptors and pixels in the grid's slot order,
  // and the first's features visited cell by cell: neighbouring features
  // have neighbouring epipolar segments, whose candidates then sit together
  // in memory (a 1280x720 keyframe's descriptors, ~10 MB, exceed the cache).
  const std::vector<int>& by_slot = grid.ItemsBySlot();
  cv::Mat slot_descriptors(n2, 128, CV_8U);
  std::vector<Eigen::Vector2d> slot_pixels(static_cast<size_t>(n2));
  for (int k = 0; k < n2; ++k) {
    const int j = by_slot[static_cast<size_t>(k)];
    std::copy_n(second.features.descriptors.ptr<std::uint8_t>(j), 128, slot_descriptors.ptr<std::uint8_t>(k));
    slot_pixels[static_cast<size_t>(k)] = second.undistorted[static_cast<size_t>(j)];
  }
  const std::vector<int> first_order = FeatureGrid(first.undistorted, cell).ItemsBySlot();

  std::vector<BestTwo> forward(static_cast<size_t>(n1)), backward(static_cast<size_t>(n2));
  // The slots in a feature's band, gathered without a branch: about one in
  // five of the features a segment visits is in its band, a branch on it
  // mispredicts often, and that cost a third of the matching.
  std::vector<int> in_band(static_cast<size_t>(n2));
  for (const int i : first_order) {
    const Eigen::Vector2d& u = first.undistorted[static_cast<size_t>(i)];
    const Eigen::Vector3d rm = r * Eigen::Vector3d((u.x() - camera.cx) / camera.fx, (u.y() - camera.cy) / camera.fy, 1.0);
    // Depths along the first camera's axis at which the ray is in front of
    // the second camera.
    double d0 = first.depth.near_m, d1 = first.depth.far_m;
    if (rm.z() > 0) d0 = std::max(d0, (min_z - t.z()) / rm.z());
    else if (rm.z() < 0) d1 = std::min(d1, (min_z - t.z()) / rm.z());
    else if (t.z() <= min_z) continue;
    if (!(d0 < d1)) continue;
    auto project = [&](double d) {
      const Eigen::Vector3d x = rm * d + t;
      return Eigen::Vector2d(camera.fx * x.x() / x.z() + camera.cx, camera.fy * x.y() / x.z() + camera.cy);
    };
    Eigen::Vector2d a = project(d0), b = project(d1);
    if (!ClipSegment(lo, hi, &a, &b)) continue;
    const Segment segment(a, b);
    const double band2 = band * band;
    const std::uint8_t* desc1 = first.features.descriptors.ptr<std::uint8_t>(i);
    BestTwo& f = forward[static_cast<size_t>(i)];
    size_t found = 0;
    grid.ForItemsNearSegment(a, b, band, [&](int, int slot) {
      in_band[found] = slot;
      found += segment.SquaredDistance(slot_pixels[static_cast<size_t>(slot)]) <= band2;
    });
    out.candidates += static_cast<long long>(found);
    for (size_t c = 0; c < found; ++c) {
      const int slot = in_band[c], j = by_slot[static_cast<size_t>(slot)];
      const std::int32_t d = SquaredDescriptorDistance(desc1, slot_descriptors.ptr<std::uint8_t>(slot));
      f.Offer(j, d);
      backward[static_cast<size_t>(j)].Offer(i, d);
    }
  }
  for (int i = 0; i < n1; ++i) {
    const BestTwo& f = forward[static_cast<size_t>(i)];
    if (!f.Passes(options.ratio, options.max_descriptor_distance)) continue;
    const BestTwo& b = backward[static_cast<size_t>(f.best)];
    if (b.best != i || !b.Passes(options.ratio, options.max_descriptor_distance)) continue;
    out.matches.push_back({i, f.best, static_cast<float>(std::sqrt(static_cast<double>(f.d1)) / kDescriptorQuantum)});
  }
  return out;
}

}  // namespace tagsfm
