#pragma once
// Running a Monte-Carlo sweep on all cores, reproducibly: work items (trials
// or cameras) are split into contiguous blocks, one per thread; each item
// seeds its own random stream from (seed, stream, item), and the blocks'
// values are merged in item order, so the numbers do not depend on the number
// of threads.
#include <algorithm>
#include <cstdint>
#include <thread>
#include <vector>

#include "tagsfm/analysis/statistics.h"

namespace tagsfm::analysis {

// The values of every (condition, metric) pair.
class Accumulator {
 public:
  Accumulator(int conditions, int metrics) : metrics_(metrics), values_(static_cast<size_t>(conditions) * metrics) {}
  void Add(int condition, int metric, double value) { values_[Index(condition, metric)].push_back(value); }
  void Append(const Accumulator& other) {
    for (size_t i = 0; i < values_.size(); ++i) {
      values_[i].insert(values_[i].end(), other.values_[i].begin(), other.values_[i].end());
    }
  }
  Summary Summarize(int condition, int metric) const { return analysis::Summarize(values_[Index(condition, metric)]); }

 private:
  size_t Index(int condition, int metric) const { return static_cast<size_t>(condition) * metrics_ + metric; }
  int metrics_;
  std::vector<std::vector<double>> values_;
};

// A well-mixed seed for item `item` of random stream `stream` (splitmix64).
inline std::uint32_t ItemSeed(std::uint32_t seed, std::uint32_t stream, std::uint32_t item) {
  std::uint64_t z = (static_cast<std::uint64_t>(seed) << 32) ^ (static_cast<std::uint64_t>(stream) << 24) ^ item;
  z += 0x9e3779b97f4a7c15ULL;
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return static_cast<std::uint32_t>(z ^ (z >> 31));
}

inline int ThreadCount(int requested) {
  if (requested > 0) return requested;
  return std::max(1u, std::thread::hardware_concurrency());
}

// Calls add_item(item, accumulator) for every item in [0, items).
template <class AddItem>
Accumulator ParallelSweep(int items, int conditions, int metrics, int threads, const AddItem& add_item) {
  const int blocks = std::max(1, std::min(ThreadCount(threads), items));
  std::vector<Accumulator> partial(blocks, Accumulator(conditions, metrics));
  std::vector<std::thread> workers;
  for (int b = 0; b < blocks; ++b) {
    workers.emplace_back([&, b] {
      const int begin = static_cast<int>(static_cast<long long>(items) * b / blocks);
      const int end = static_cast<int>(static_cast<long long>(items) * (b + 1) / blocks);
      for (int item = begin; item < end; ++item) add_item(item, partial[b]);
    });
  }
  for (std::thread& worker : workers) worker.join();
  Accumulator merged(conditions, metrics);
  for (const Accumulator& block : partial) merged.Append(block);
  return merged;
}

}  // namespace tagsfm::analysis
