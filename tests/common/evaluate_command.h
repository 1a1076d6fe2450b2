#pragma once
// `tagsfm evaluate OUT REC` from a test, and the figures the metrology
// tests read from it.
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "json_file.h"
#include "run_command.h"
#include "test_paths.h"

namespace tagsfm::testing {

// The result OUT scored against REC's truth; its stderr and JSON go into
// `dir`. Null (after a failure naming why) when the command fails.
inline nlohmann::json EvaluateAgainstTruth(const std::filesystem::path& out, const std::filesystem::path& rec,
                                           const std::filesystem::path& dir) {
  const int code = RunCommand(TagsfmExe().string() + " evaluate " + out.string() + " " + rec.string() + " 2> " +
                                  (dir / "eval.err").string(),
                              dir / "eval.json");
  if (code != 0) {
    ADD_FAILURE() << "tagsfm evaluate " << out.string() << ": exit " << code << ": " << ReadText(dir / "eval.err");
    return nlohmann::json();
  }
  return ReadJsonFile(dir / "eval.json");
}

// Each tag pair's length error over its sigma (pairs with a sigma only).
inline std::vector<double> LengthErrorsOverSigma(const nlohmann::json& evaluation) {
  std::vector<double> ratios;
  if (!evaluation.is_object() || !evaluation.contains("lengths") || !evaluation["lengths"].is_object()) return ratios;
  for (const auto& pair : evaluation["lengths"]["pairs"]) {
    if (pair["sigma_m"].is_number() && pair["sigma_m"].get<double>() > 0) {
      ratios.push_back(pair["error_m"].get<double>() / pair["sigma_m"].get<double>());
    }
  }
  return ratios;
}

// Mean, sample standard deviation and how many lie beyond 3 of E/sigma
// pooled over pairs: an honest sigma gives about 0, 1 and 0.3 %.
struct PooledRatios {
  double mean = 0, std_dev = 0;
  int beyond_3 = 0;
};
inline PooledRatios Pool(const std::vector<double>& ratios) {
  PooledRatios p;
  if (ratios.size() < 2) return p;
  for (double r : ratios) {
    p.mean += r / static_cast<double>(ratios.size());
    p.beyond_3 += std::abs(r) > 3;
  }
  double sum_sq = 0;
  for (double r : ratios) sum_sq += (r - p.mean) * (r - p.mean);
  p.std_dev = std::sqrt(sum_sq / static_cast<double>(ratios.size() - 1));
  return p;
}

}  // namespace tagsfm::testing
