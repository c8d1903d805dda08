#include "runtime/ppe/body_maths.h"

#include <algorithm>
#include <cmath>
#include <cstring>

#include "runtime/base/quat.h"

namespace cellphys::ppe {

void set_mass_properties(const ShapeDictionary& shapes, const BodyDesc& d, const std::string& who, WorldBody& b) {
  const BodyMass m = body_mass(shapes, d.shape, d.scale, d.mass, d.density);  // throws ShapeError on bad input
  b.mass = m.mass;
  std::copy(m.inertia, m.inertia + 6, b.inertia);
  if (d.has_inertia) std::copy(d.inertia, d.inertia + 6, b.inertia);
  if (!invert_inertia(b.inertia, b.inverse_inertia)) throw WorldError(who + ": inertia tensor is not invertible");
}

void apply_impulse(WorldBody& b, const float impulse[3], const float point[3]) {
  const Vec3d r = {point[0] - double(b.state.position[0]), point[1] - double(b.state.position[1]), point[2] - double(b.state.position[2])};
  const Vec3d J = {impulse[0], impulse[1], impulse[2]};
  const Vec3d L = {r.y * J.z - r.z * J.y, r.z * J.x - r.x * J.z, r.x * J.y - r.y * J.x};
  const Quatd q{b.state.orientation[0], b.state.orientation[1], b.state.orientation[2], b.state.orientation[3]};
  const Vec3d dw = mul(rotate_sym(quat_to_matrix(q), b.inverse_inertia), L);
  for (int k = 0; k < 3; ++k) b.state.velocity[k] += static_cast<float>(impulse[k] / b.mass);
  b.state.angular_velocity[0] += float(dw.x), b.state.angular_velocity[1] += float(dw.y), b.state.angular_velocity[2] += float(dw.z);
}

void add_kinetic_energy(const WorldBody& b, double& e) {
  e += 0.5 * b.mass *
       (double(b.state.velocity[0]) * b.state.velocity[0] + double(b.state.velocity[1]) * b.state.velocity[1] + double(b.state.velocity[2]) * b.state.velocity[2]);
  const Quatd q{b.state.orientation[0], b.state.orientation[1], b.state.orientation[2], b.state.orientation[3]};
  const Vec3d w = {b.state.angular_velocity[0], b.state.angular_velocity[1], b.state.angular_velocity[2]};
  const Vec3d Iw = mul(rotate_sym(quat_to_matrix(q), b.inertia), w);
  e += 0.5 * (w.x * Iw.x + w.y * Iw.y + w.z * Iw.z);
}

uint64_t hash_state(const WorldBody& b, uint64_t h) {
  const float* parts[4] = {b.state.position, b.state.orientation, b.state.velocity, b.state.angular_velocity};
  const int n[4] = {3, 4, 3, 3};
  for (int p = 0; p < 4; ++p)
    for (int k = 0; k < n[p]; ++k) {
      uint32_t bits;
      std::memcpy(&bits, parts[p] + k, 4);
      h = (h ^ bits) * 0x100000001B3ull;
    }
  return h;
}

}  // namespace cellphys::ppe
