#pragma once
// A small persistent pool for the per-frame parallel work of detection (tag
// refinement, tracking regions): the threads are started once, not per
// frame, so that handing out a few jobs of ~0.1-1 ms each pays off.
#include <condition_variable>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

namespace tagsfm::detail {

class DetectionWorkers {
 public:
  // `threads` >= 1 in all: the caller's thread plus threads - 1 workers.
  explicit DetectionWorkers(int threads);
  ~DetectionWorkers();
  DetectionWorkers(const DetectionWorkers&) = delete;
  DetectionWorkers& operator=(const DetectionWorkers&) = delete;

  int threads() const { return static_cast<int>(workers_.size()) + 1; }

  // Calls job(i, thread) for every i in [0, jobs) and returns when all are
  // done. `thread` in [0, threads()) names the thread running the job, for
  // per-thread scratch state (never two jobs at once with the same value).
  // Jobs are handed out one at a time, so uneven jobs balance.
  void Run(int jobs, const std::function<void(int job, int thread)>& job);

 private:
  void WorkerLoop(int thread);
  void Drain(int thread);

  std::vector<std::thread> workers_;
  std::mutex mutex_;
  std::condition_variable start_;
  std::condition_variable done_;
  const std::function<void(int, int)>* job_ = nullptr;
  int jobs_ = 0;
  int next_job_ = 0;
  int busy_ = 0;            // workers inside the current batch
  unsigned generation_ = 0;  // counts batches, wakes the workers
  bool stop_ = false;
};

}  // namespace tagsfm::detail
