#pragma once
// Doubles as text for the result files: the shortest digits that read back
// to the same double (std::to_chars). As exact as printf's "%.17g" and
// several times faster (glibc formats "%.17g" with multi-precision
// arithmetic), and a result holds millions of them (docs/features.md).
#include <ostream>

namespace tagsfm {

struct ExactDouble {
  double value;
};

// `out << ExactText(x)` writes x in its shortest exact form.
inline ExactDouble ExactText(double value) { return {value}; }
std::ostream& operator<<(std::ostream& out, ExactDouble number);

}  // namespace tagsfm
