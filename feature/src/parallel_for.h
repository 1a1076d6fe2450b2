#pragma once
// body(i) for every i in [0, n) on `threads` threads (the caller's among
// them), items handed out in blocks of `block` from a shared counter. Each
// item writes only its own output, so the result is the same for any
// thread count.
#include <algorithm>
#include <atomic>
#include <cstddef>
#include <thread>
#include <vector>

namespace tagsfm {

template <typename Body>
void ParallelFor(size_t n, int threads, Body&& body, size_t block = 16) {
  const size_t kBlock = std::max<size_t>(1, block);
  if (threads <= 1 || n <= kBlock) {
    for (size_t i = 0; i < n; ++i) body(i);
    return;
  }
  std::atomic<size_t> next{0};
  auto work = [&] {
    for (size_t begin; (begin = next.fetch_add(kBlock)) < n;) {
      for (size_t i = begin; i < std::min(n, begin + kBlock); ++i) body(i);
    }
  };
  std::vector<std::thread> pool;
  for (int t = 1; t < threads; ++t) pool.emplace_back(work);
  work();
  for (std::thread& t : pool) t.join();
}

}  // namespace tagsfm
