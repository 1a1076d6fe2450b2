#include "tagsfm/core/peak_rss.h"

#include <cstdlib>
#include <fstream>
#include <string>

namespace tagsfm {

double PeakRssMb() {
  std::ifstream status("/proc/self/status");
  std::string line;
  while (std::getline(status, line)) {
    if (line.rfind("VmHWM:", 0) == 0) return std::atof(line.c_str() + 6) / 1024.0;  // kB
  }
  return 0;
}

}  // namespace tagsfm
