#include "server/quantise.h"

#include <algorithm>
#include <cmath>

namespace cellphys::server {

namespace {

constexpr double kRange = 32767.0;
constexpr double kInvSqrt2 = 0.70710678118654752440;
constexpr double kOrientLevels = 1023.0;  // 10 bits

int16_t to_step(double v, double step) {
  if (!(step > 0)) return 0;
  const double q = std::nearbyint(v / step);
  return static_cast<int16_t>(std::clamp(q, -kRange, kRange));
}

}  // namespace

protocol::QuantFrame quant_frame(const ppe::BodyState* const* states, size_t n) {
  protocol::QuantFrame f{};
  if (n == 0) return f;
  double lo[3], hi[3];
  for (int k = 0; k < 3; ++k) lo[k] = hi[k] = states[0]->position[k];
  double vmax = 0, wmax = 0;
  for (size_t i = 0; i < n; ++i) {
    const ppe::BodyState& s = *states[i];
    for (int k = 0; k < 3; ++k) {
      lo[k] = std::min(lo[k], double(s.position[k]));
      hi[k] = std::max(hi[k], double(s.position[k]));
      vmax = std::max(vmax, std::fabs(double(s.velocity[k])));
      wmax = std::max(wmax, std::fabs(double(s.angular_velocity[k])));
    }
  }
  double half = 0;
  for (int k = 0; k < 3; ++k) {
    f.origin[k] = static_cast<float>(0.5 * (lo[k] + hi[k]));
    half = std::max({half, hi[k] - f.origin[k], f.origin[k] - lo[k]});  // against the float origin
  }
  // Rounded up to float so the largest component never maps past the 16-bit range.
  f.position_step = std::nextafter(static_cast<float>(half / kRange), 1e30f);
  f.velocity_step = std::nextafter(static_cast<float>(vmax / kRange), 1e30f);
  f.angular_step = std::nextafter(static_cast<float>(wmax / kRange), 1e30f);
  return f;
}

uint32_t pack_orientation(const float q[4]) {
  int largest = 0;
  for (int k = 1; k < 4; ++k)
    if (std::fabs(q[k]) > std::fabs(q[largest])) largest = k;
  const double sign = q[largest] < 0 ? -1.0 : 1.0;
  uint32_t bits = static_cast<uint32_t>(largest) << 30;
  int slot = 0;
  for (int k = 0; k < 4; ++k) {
    if (k == largest) continue;
    const double c = std::clamp(sign * q[k] / kInvSqrt2, -1.0, 1.0);  // in [-1, 1]
    const uint32_t level = static_cast<uint32_t>(std::nearbyint((c * 0.5 + 0.5) * kOrientLevels));
    bits |= level << (10 * slot++);
  }
  return bits;
}

void unpack_orientation(uint32_t bits, float q[4]) {
  const int largest = static_cast<int>(bits >> 30);
  double c[4], sum = 0;
  int slot = 0;
  for (int k = 0; k < 4; ++k) {
    if (k == largest) continue;
    const double level = double((bits >> (10 * slot++)) & 1023u);
    c[k] = (level / kOrientLevels * 2.0 - 1.0) * kInvSqrt2;
    sum += c[k] * c[k];
  }
  c[largest] = std::sqrt(std::max(0.0, 1.0 - sum));
  double n = 0;
  for (double v : c) n += v * v;
  n = std::sqrt(n);
  for (int k = 0; k < 4; ++k) q[k] = static_cast<float>(c[k] / n);
}

void quantise(const ppe::BodyState& s, const protocol::QuantFrame& f, protocol::BodyMovedQ& out) {
  for (int k = 0; k < 3; ++k) {
    out.position[k] = to_step(double(s.position[k]) - f.origin[k], f.position_step);
    out.velocity[k] = to_step(s.velocity[k], f.velocity_step);
    out.angular_velocity[k] = to_step(s.angular_velocity[k], f.angular_step);
  }
  out.orientation = pack_orientation(s.orientation);
  out.reserved = 0;
}

void dequantise(const protocol::BodyMovedQ& q, const protocol::QuantFrame& f, ppe::BodyState& out) {
  for (int k = 0; k < 3; ++k) {
    out.position[k] = static_cast<float>(double(f.origin[k]) + double(f.position_step) * q.position[k]);
    out.velocity[k] = static_cast<float>(double(f.velocity_step) * q.velocity[k]);
    out.angular_velocity[k] = static_cast<float>(double(f.angular_step) * q.angular_velocity[k]);
  }
  unpack_orientation(q.orientation, out.orientation);
}

}  // namespace cellphys::server
