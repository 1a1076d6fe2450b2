#include "tagsfm/core/number_text.h"

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <random>
#include <sstream>
#include <string>

#include <gtest/gtest.h>

namespace tagsfm {
namespace {

bool SameBits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }

std::string FormatDouble(double x) {
  std::ostringstream out;
  out << ExactText(x);
  return out.str();
}

// Every double a result file holds must read back to itself, bit for bit:
// values over the whole range (coordinates, covariances of 1e-12 m^2,
// subnormals, the extremes), and signed zero.
TEST(NumberText, EveryDoubleReadsBackToItself) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> mantissa(-1, 1);
  std::uniform_int_distribution<int> exponent(-320, 308);
  for (int i = 0; i < 200000; ++i) {
    const double v = std::ldexp(mantissa(rng), exponent(rng));
    const double x = std::isfinite(v) ? v : 1.0;
    ASSERT_TRUE(SameBits(std::strtod(FormatDouble(x).c_str(), nullptr), x)) << FormatDouble(x);
  }
  for (const double x : {0.0, -0.0, 1.0, -1.0, 0.1, 1e-7, std::numeric_limits<double>::max(),
                         std::numeric_limits<double>::lowest(), std::numeric_limits<double>::min(),
                         std::numeric_limits<double>::denorm_min(), 4.5888154933608885e-07}) {
    EXPECT_TRUE(SameBits(std::strtod(FormatDouble(x).c_str(), nullptr), x)) << FormatDouble(x);
  }
}

// The shortest exact form: no more digits than the value needs, where
// "%.17g" pads 0.1 to 0.10000000000000001.
TEST(NumberText, WritesTheShortestExactDigits) {
  EXPECT_EQ(FormatDouble(0.1), "0.1");
  EXPECT_EQ(FormatDouble(-2.5), "-2.5");
  EXPECT_EQ(FormatDouble(3.0), "3");
  EXPECT_EQ(FormatDouble(1e-7), "1e-07");
  EXPECT_EQ(FormatDouble(0.30000000000000004), "0.30000000000000004");  // 0.1 + 0.2 needs all 17
  std::ostringstream out;
  out << ExactText(0.1) << ',' << ExactText(1e300);
  EXPECT_EQ(out.str(), "0.1,1e+300");
  EXPECT_EQ(FormatDouble(std::numeric_limits<double>::infinity()), "inf");
  EXPECT_EQ(FormatDouble(-std::numeric_limits<double>::infinity()), "-inf");
}

}  // namespace
}  // namespace tagsfm
