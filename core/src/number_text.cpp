#include "tagsfm/core/number_text.h"

#include <charconv>

namespace tagsfm {

std::ostream& operator<<(std::ostream& out, ExactDouble number) {
  // The longest shortest form of a double is 24 characters
  // ("-2.2250738585072014e-308").
  char buffer[32];
  const char* end = std::to_chars(buffer, buffer + sizeof buffer, number.value).ptr;
  return out.write(buffer, end - buffer);
}

}  // namespace tagsfm
