#pragma once
// Pieces shared by the experiments: the condition grid of a sweep and the
// pose metrics of one solved trial.
#include <cstdio>
#include <random>
#include <string>
#include <vector>

#include "sweep.h"
#include "tagsfm/analysis/experiment_result.h"
#include "tagsfm/analysis/metrics.h"
#include "tagsfm/analysis/synthetic_scene.h"

namespace tagsfm::analysis {

// Metric names used in the CSV files (the unit is in the name).
inline constexpr const char* kPositionalError = "positional_error_units";     // eq. 3
inline constexpr const char* kRotationalError = "rotational_error_eq2";       // eq. 2
inline constexpr const char* kRotationDeg = "rotation_error_deg";
inline constexpr const char* kReprojectionError = "reprojection_error_px";    // eq. 1

inline std::string FormatValue(double value) {
  char buffer[32];
  std::snprintf(buffer, sizeof(buffer), "%g", value);
  return buffer;
}

// Conditions facet x series x xs; condition index = (facet * series + s) * xs + x.
struct Grid {
  std::vector<std::string> facets = {""};
  std::vector<std::string> series;
  std::vector<double> xs;
  int Conditions() const { return static_cast<int>(facets.size() * series.size() * xs.size()); }
  int Index(int facet, int s, int x) const {
    return (facet * static_cast<int>(series.size()) + s) * static_cast<int>(xs.size()) + x;
  }
};

inline void AddRows(ExperimentResult& result, const std::string& object, const Grid& grid,
                    const std::vector<std::string>& metrics, const Accumulator& values) {
  for (size_t f = 0; f < grid.facets.size(); ++f) {
    for (size_t s = 0; s < grid.series.size(); ++s) {
      for (size_t x = 0; x < grid.xs.size(); ++x) {
        for (size_t m = 0; m < metrics.size(); ++m) {
          const int condition = grid.Index(static_cast<int>(f), static_cast<int>(s), static_cast<int>(x));
          result.rows.push_back({object, grid.facets[f], grid.series[s], grid.xs[x], metrics[m],
                                 values.Summarize(condition, static_cast<int>(m))});
        }
      }
    }
  }
}

// The four pose metrics, in this order, for the experiments that solve poses.
inline const std::vector<std::string>& PoseMetrics() {
  static const std::vector<std::string> metrics = {kReprojectionError, kRotationalError, kRotationDeg,
                                                   kPositionalError};
  return metrics;
}

// Adds the PoseMetrics() of one estimate: eq. 1 of `points` (as the solver
// saw them) against `observed` pixels, eq. 2-3 against the true pose.
inline void AddPoseMetrics(Accumulator& values, int condition, const Rigid3d& estimated, const Rigid3d& truth,
                           const std::vector<Eigen::Vector3d>& points, const std::vector<Eigen::Vector2d>& observed,
                           const CameraModel& camera) {
  const PoseErrors errors = ComparePoses(estimated, truth);
  values.Add(condition, 0, MeanReprojectionError(estimated, points, observed, [&](const Eigen::Vector3d& p) {
               return ProjectToPixel(camera, p);
             }));
  values.Add(condition, 1, errors.rotation_eq2);
  values.Add(condition, 2, errors.rotation_deg);
  values.Add(condition, 3, errors.position);
}

// `count` distinct elements of `pool`, uniformly (partial Fisher-Yates on a copy).
inline std::vector<int> SampleWithoutReplacement(std::vector<int> pool, int count, std::mt19937& rng) {
  for (int i = 0; i < count; ++i) {
    std::uniform_int_distribution<int> pick(i, static_cast<int>(pool.size()) - 1);
    std::swap(pool[i], pool[pick(rng)]);
  }
  pool.resize(count);
  return pool;
}

}  // namespace tagsfm::analysis
