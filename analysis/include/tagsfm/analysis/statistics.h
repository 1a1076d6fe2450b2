#pragma once
// Summary statistics of one experimental condition.
#include <vector>

namespace tagsfm::analysis {

struct Summary {
  double mean = 0;
  double std = 0;     // sample standard deviation (n - 1); 0 for fewer than 2 values
  double median = 0;
  double rms = 0;     // root mean square, what the error model predicts
  int count = 0;
};

// Non-finite values are left out (and not counted). Takes a copy to sort.
Summary Summarize(std::vector<double> values);

}  // namespace tagsfm::analysis
