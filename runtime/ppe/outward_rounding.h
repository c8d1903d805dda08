// Doubles to floats rounded away from the inside of a box: a float box made of these always
// holds the double one (the shape dictionary's boxes, a surface hierarchy's nodes).
#pragma once
#include <cstdint>
#include <cstring>

namespace cellphys::ppe {

namespace outward_detail {
// The float next to f, below (step -1) or above (+1): std::nextafter's result for any f that
// is not NaN, by the bits, without its library call (one a bound: six a body's box each step).
inline float next_float(float f, int step) {
  uint32_t u;
  std::memcpy(&u, &f, sizeof u);
  if (f == 0.0f) u = step > 0 ? 1u : 0x80000001u;  // from either zero: the smallest subnormals
  else u = (f > 0.0f) == (step > 0) ? u + 1 : u - 1;  // away from zero, or towards it
  std::memcpy(&f, &u, sizeof f);
  return f;
}
}  // namespace outward_detail

/// The largest float not above v.
inline float round_down(double v) {
  const float f = static_cast<float>(v);
  return static_cast<double>(f) > v ? outward_detail::next_float(f, -1) : f;
}
/// The smallest float not below v.
inline float round_up(double v) {
  const float f = static_cast<float>(v);
  return static_cast<double>(f) < v ? outward_detail::next_float(f, 1) : f;
}

}  // namespace cellphys::ppe
