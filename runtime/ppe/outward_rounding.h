// Doubles to floats rounded away from the inside of a box: a float box made of these always
// holds the double one (the shape dictionary's boxes, a surface hierarchy's nodes).
#pragma once
#include <cmath>
#include <limits>

namespace cellphys::ppe {

/// The largest float not above v.
inline float round_down(double v) {
  float f = static_cast<float>(v);
  if (static_cast<double>(f) > v) f = std::nextafter(f, -std::numeric_limits<float>::infinity());
  return f;
}
/// The smallest float not below v.
inline float round_up(double v) {
  float f = static_cast<float>(v);
  if (static_cast<double>(f) < v) f = std::nextafter(f, std::numeric_limits<float>::infinity());
  return f;
}

}  // namespace cellphys::ppe
