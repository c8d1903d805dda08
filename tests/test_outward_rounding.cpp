// round_down and round_up against their definition: the float nearest v, stepped by
// std::nextafter past v when it lies inside; over zeros of both signs, subnormals, the largest
// floats and infinities, and doubles of every magnitude. The box of every shape rests on them.
#include "runtime/ppe/outward_rounding.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <random>

namespace cellphys::ppe {
namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();

uint32_t bits(float f) {
  uint32_t u;
  std::memcpy(&u, &f, sizeof u);
  return u;
}

float expected_down(double v) {
  float f = static_cast<float>(v);
  if (static_cast<double>(f) > v) f = std::nextafter(f, -kInf);
  return f;
}
float expected_up(double v) {
  float f = static_cast<float>(v);
  if (static_cast<double>(f) < v) f = std::nextafter(f, kInf);
  return f;
}

void expect_same(double v) {
  EXPECT_EQ(bits(round_down(v)), bits(expected_down(v))) << v;
  EXPECT_EQ(bits(round_up(v)), bits(expected_up(v))) << v;
  EXPECT_LE(static_cast<double>(round_down(v)), v);
  EXPECT_GE(static_cast<double>(round_up(v)), v);
}

TEST(OutwardRounding, EdgesAsNextafter) {
  const double fmax = std::numeric_limits<float>::max(), tiny = std::numeric_limits<float>::denorm_min();
  const double dinf = std::numeric_limits<double>::infinity();
  for (double v : {0.0, -0.0, tiny, -tiny, tiny / 3, -tiny / 3, 1e-300, -1e-300, 1.5 * tiny, -1.5 * tiny,
                   double(std::numeric_limits<float>::min()) * (1 - 1e-9), fmax, -fmax, fmax * (1 + 1e-12),
                   -fmax * (1 + 1e-12), fmax * 2, -fmax * 2, 1e300, -1e300, dinf, -dinf, 1.0, -1.0, 0.1, -0.1,
                   1.0 + 1e-12, -1.0 - 1e-12})
    expect_same(v);
}

TEST(OutwardRounding, RandomDoublesAsNextafter) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> mantissa(-1.0, 1.0);
  std::uniform_int_distribution<int> exponent(-160, 140);
  for (int i = 0; i < 200000; ++i) expect_same(std::ldexp(mantissa(rng), exponent(rng)));
  // floats exactly: nothing to round
  for (int i = 0; i < 1000; ++i) {
    const float f = static_cast<float>(std::ldexp(mantissa(rng), exponent(rng) / 2));
    EXPECT_EQ(round_down(f), f);
    EXPECT_EQ(round_up(f), f);
  }
}

}  // namespace
}  // namespace cellphys::ppe
