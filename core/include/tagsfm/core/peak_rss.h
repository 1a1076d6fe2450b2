#pragma once
// Peak resident memory of this process, for run reports and benchmarks.

namespace tagsfm {

// VmHWM from /proc/self/status, in MB; 0 if unknown.
double PeakRssMb();

}  // namespace tagsfm
