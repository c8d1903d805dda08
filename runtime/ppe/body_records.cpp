#include "runtime/ppe/body_records.h"

#include <cmath>

#include "runtime/ppe/mass_properties.h"

namespace cellphys::ppe {

spu::Pose pose_of(const WorldBody& b) {
  spu::Pose p;
  for (int k = 0; k < 3; ++k) p.position[k] = b.state.position[k];
  for (int k = 0; k < 4; ++k) p.orientation[k] = b.state.orientation[k];
  p.scale = b.scale;
  return p;
}

bool invert_inertia(const float* I, float* inv) {
  const double a = I[0], b = I[1], c = I[2], xy = I[3], xz = I[4], yz = I[5];
  // [[a xy xz] [xy b yz] [xz yz c]]
  const double c00 = b * c - yz * yz, c01 = xz * yz - xy * c, c02 = xy * yz - xz * b;
  const double det = a * c00 + xy * c01 + xz * c02;
  if (!(std::fabs(det) > 0.0) || !std::isfinite(det)) return false;
  const double c11 = a * c - xz * xz, c12 = xy * xz - a * yz, c22 = a * b - xy * xy;
  inv[0] = float(c00 / det), inv[1] = float(c11 / det), inv[2] = float(c22 / det);
  inv[3] = float(c01 / det), inv[4] = float(c02 / det), inv[5] = float(c12 / det);
  for (int k = 0; k < 6; ++k)
    if (!std::isfinite(inv[k])) return false;
  return true;
}

}  // namespace cellphys::ppe

namespace cellphys::ppe {

BodyMass body_mass(const ShapeDictionary& shapes, uint32_t shape, float scale, float mass, float density) {
  const MassProperties m = mass > 0.0f ? mass_properties_from_mass(shapes, shape, scale, mass)
                                       : mass_properties_from_density(shapes, shape, scale, density);
  BodyMass b;
  b.mass = static_cast<float>(m.mass);
  for (int k = 0; k < 6; ++k) b.inertia[k] = static_cast<float>(m.inertia[k]);
  return b;
}

}  // namespace cellphys::ppe
