// The mechanics of one world body outside the step: its mass properties from a description,
// impulses, kinetic energy, and the bits of its state for determinism checks.
#pragma once
#include <cstdint>
#include <vector>

#include "runtime/base/mat3.h"
#include "runtime/base/vec3.h"
#include "runtime/ppe/body_records.h"
#include "runtime/ppe/world.h"

namespace cellphys::ppe {

/// Mass, inertia and its inverse of a dynamic body from a checked description (mass or
/// density, the shape's inertia unless the description gives one). Throws WorldError (`who`
/// names the body) or ShapeError.
void set_mass_properties(const ShapeDictionary& shapes, const BodyDesc& d, const std::string& who, WorldBody& b);

/// An impulse (N s) at a world point: v += J / m, w += I_world^-1 (r x J).
void apply_impulse(WorldBody& b, const float impulse[3], const float point[3]);

/// Adds 1/2 m v^2, then 1/2 w^T I_world w (J) to e: a world's energy is summed term by term
/// in body order (the total's last bits depend on that order).
void add_kinetic_energy(const WorldBody& b, double& e);

/// The velocity change along n at world point p per unit impulse along n, of a body with inverse
/// mass w, world inverse inertia Iinv and centre x: 1/m + (r x n)^T I^-1 (r x n).
inline double inverse_mass_along(double w, const Mat3d& Iinv, const Vec3d& x, const Vec3d& p, const Vec3d& n) {
  const Vec3d rn = cross(p - x, n);
  return w + dot(rn, mul(Iinv, rn));
}

/// The velocity of body `id`'s material point at world point p (zero for the world, kWorldBody).
inline Vec3d velocity_at(const std::vector<WorldBody>& bodies, uint32_t id, const Vec3d& p) {
  if (id == kWorldBody) return {0, 0, 0};
  const BodyState& s = bodies[id].state;
  return Vec3d::load(s.velocity) + cross(Vec3d::load(s.angular_velocity), p - Vec3d::load(s.position));
}

/// FNV-1a over the bits of a body's position, orientation and velocities, continuing h.
uint64_t hash_state(const WorldBody& b, uint64_t h);

}  // namespace cellphys::ppe
