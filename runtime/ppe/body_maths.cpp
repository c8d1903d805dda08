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
  const Vec3d r = Vec3d::load(point) - Vec3d::load(b.state.position);
  const Vec3d L = cross(r, Vec3d::load(impulse));
  const Vec3d dw = mul(rotate_sym(quat_to_matrix(Quatd::load(b.state.orientation)), b.inverse_inertia), L);
  for (int k = 0; k < 3; ++k) b.state.velocity[k] += static_cast<float>(impulse[k] / b.mass);
  b.state.angular_velocity[0] += float(dw.x), b.state.angular_velocity[1] += float(dw.y), b.state.angular_velocity[2] += float(dw.z);
}

void add_kinetic_energy(const WorldBody& b, double& e) {
  e += 0.5 * b.mass * squared_norm(Vec3d::load(b.state.velocity));
  const Vec3d w = Vec3d::load(b.state.angular_velocity);
  const Vec3d Iw = mul(rotate_sym(quat_to_matrix(Quatd::load(b.state.orientation)), b.inertia), w);
  e += 0.5 * dot(w, Iw);
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
