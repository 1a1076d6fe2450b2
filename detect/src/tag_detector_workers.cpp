#include "tag_detector_workers.h"

#include <algorithm>

namespace tagsfm::detail {

DetectionWorkers::DetectionWorkers(int threads) {
  for (int t = 1; t < std::max(1, threads); ++t) workers_.emplace_back([this, t] { WorkerLoop(t); });
}

DetectionWorkers::~DetectionWorkers() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  start_.notify_all();
  for (std::thread& worker : workers_) worker.join();
}

void DetectionWorkers::Run(int jobs, const std::function<void(int job, int thread)>& job) {
  if (jobs <= 0) return;
  if (workers_.empty() || jobs == 1) {
    for (int i = 0; i < jobs; ++i) job(i, 0);
    return;
  }
  {
    std::lock_guard<std::mutex> lock(mutex_);
    job_ = &job;
    jobs_ = jobs;
    next_job_ = 0;
    busy_ = static_cast<int>(workers_.size());
    ++generation_;
  }
  start_.notify_all();
  Drain(0);
  std::unique_lock<std::mutex> lock(mutex_);
  done_.wait(lock, [this] { return busy_ == 0; });
  job_ = nullptr;
}

// Takes jobs until none is left.
void DetectionWorkers::Drain(int thread) {
  for (;;) {
    int i;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (next_job_ >= jobs_) return;
      i = next_job_++;
    }
    (*job_)(i, thread);
  }
}

void DetectionWorkers::WorkerLoop(int thread) {
  unsigned seen = 0;
  for (;;) {
    {
      std::unique_lock<std::mutex> lock(mutex_);
      start_.wait(lock, [&] { return stop_ || generation_ != seen; });
      if (stop_) return;
      seen = generation_;
    }
    Drain(thread);
    {
      std::lock_guard<std::mutex> lock(mutex_);
      --busy_;
    }
    done_.notify_one();
  }
}

}  // namespace tagsfm::detail
