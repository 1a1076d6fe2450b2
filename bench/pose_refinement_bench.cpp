// The pose refinement's cost per call, on a frame's mapped corners (20 tags,
// 80 points) and on one tag's four corners (TagPoseCandidates refines both
// IPPE branches of every tag the dashboard's coverage sees, every frame).
// Counters: the reprojection RMS reached (px), to compare implementations
// on accuracy as well as time.
#include <cmath>
#include <random>
#include <vector>

#include <benchmark/benchmark.h>

#include "tagsfm/recon/pose_estimator.h"
#include "tagsfm/recon/tag_geometry.h"

namespace tagsfm {
namespace {

constexpr double kFocalPx = 1000;

struct PoseCase {
  std::vector<Eigen::Vector3d> points;
  std::vector<Eigen::Vector2d> normalized;
  std::vector<int> use;
  Rigid3d truth, start;
};

// `tags` tags of 6 cm spread over a 2 m wall 2.5 m away, 0.3 px noise; the
// start is the truth turned 0.5 degrees and moved 1 cm (what EPnP hands on).
PoseCase MakeCase(int tags, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> across(-1.0, 1.0);
  std::normal_distribution<double> noise(0.0, 0.3 / kFocalPx);
  PoseCase c;
  c.truth = Rigid3d(Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d(0.2, 1, 0.1).normalized())),
                    Eigen::Vector3d(0.1, -0.05, 2.5));
  for (int t = 0; t < tags; ++t) {
    const Eigen::Vector3d centre = tags == 1 ? Eigen::Vector3d::Zero() : Eigen::Vector3d(across(rng), across(rng), 0.2 * across(rng));
    for (int k = 0; k < 4; ++k) {
      const Eigen::Vector3d p = centre + TagCornerInTag(k, 0.06);
      c.points.push_back(p);
      c.normalized.push_back((c.truth * p).hnormalized() + Eigen::Vector2d(noise(rng), noise(rng)));
      c.use.push_back(static_cast<int>(c.use.size()));
    }
  }
  c.start = Rigid3d(Eigen::Quaterniond(Eigen::AngleAxisd(0.5 * M_PI / 180, Eigen::Vector3d::UnitY())) * c.truth.rotation,
                    c.truth.translation + Eigen::Vector3d(0.01, 0, 0));
  return c;
}

double RmsPx(const PoseCase& c, const Rigid3d& pose) {
  double sum = 0;
  for (size_t i = 0; i < c.points.size(); ++i) {
    sum += (kFocalPx * ((pose * c.points[i]).hnormalized() - c.normalized[i])).squaredNorm();
  }
  return std::sqrt(sum / static_cast<double>(c.points.size()));
}

void BM_RefinePose(benchmark::State& state) {
  const PoseCase c = MakeCase(static_cast<int>(state.range(0)), 7);
  Rigid3d refined;
  for (auto _ : state) {
    refined = RefinePose(c.points, c.normalized, c.use, kFocalPx, kFocalPx, c.start, 1.0, 20);
    benchmark::DoNotOptimize(refined);
  }
  state.counters["rms_px"] = RmsPx(c, refined);
  state.counters["rotation_error_deg"] = refined.rotation.angularDistance(c.truth.rotation) * 180 / M_PI;
}
BENCHMARK(BM_RefinePose)->Arg(1)->Arg(20);

void BM_TagPoseCandidates(benchmark::State& state) {
  const PoseCase c = MakeCase(1, 11);
  const std::array<Eigen::Vector2d, 4> corners{c.normalized[0], c.normalized[1], c.normalized[2], c.normalized[3]};
  std::vector<Rigid3d> candidates;
  for (auto _ : state) {
    candidates = TagPoseCandidates(corners, 0.06);
    benchmark::DoNotOptimize(candidates);
  }
  state.counters["best_rotation_error_deg"] =
      candidates.empty() ? -1 : candidates.front().rotation.angularDistance(c.truth.rotation) * 180 / M_PI;
}
BENCHMARK(BM_TagPoseCandidates);

}  // namespace
}  // namespace tagsfm

BENCHMARK_MAIN();
