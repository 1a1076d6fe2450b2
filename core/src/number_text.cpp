#include "tagsfm/core/number_text.h"

#include <charconv>

namespace tagsfm {
namespace {

// The longest shortest form of a double is 24 characters
// ("-2.2250738585072014e-308").
constexpr int kMaxChars = 32;

int ToChars(double value, char* buffer) {
  return static_cast<int>(std::to_chars(buffer, buffer + kMaxChars, value).ptr - buffer);
}

}  // namespace

std::ostream& operator<<(std::ostream& out, ExactDouble number) {
  char buffer[kMaxChars];
  return out.write(buffer, ToChars(number.value, buffer));
}

std::string FormatDouble(double value) {
  char buffer[kMaxChars];
  return std::string(buffer, static_cast<size_t>(ToChars(value, buffer)));
}

}  // namespace tagsfm
