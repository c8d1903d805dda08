// The mechanics of one world body outside the step: its mass properties from a description,
// impulses, kinetic energy, and the bits of its state for determinism checks.
#pragma once
#include <cstdint>

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

/// FNV-1a over the bits of a body's position, orientation and velocities, continuing h.
uint64_t hash_state(const WorldBody& b, uint64_t h);

}  // namespace cellphys::ppe
