#pragma once
// CPU time of the calling thread: on a shared machine the wall clock also
// counts time the scheduler gave to other processes.
#include <ctime>

namespace tagsfm {

inline double ThreadCpuMs() {
  timespec t{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return 1e3 * static_cast<double>(t.tv_sec) + 1e-6 * static_cast<double>(t.tv_nsec);
}

}  // namespace tagsfm
