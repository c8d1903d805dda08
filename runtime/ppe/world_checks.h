// What the world refuses at its API: each check throws WorldError naming the body or force,
// the field and the reason, before anything changes.
#pragma once
#include <string>
#include <vector>

#include "cellphys/gen/force_table.h"
#include "runtime/ppe/world.h"

namespace cellphys::ppe {

/// A body description: shape, scale, finite pose and velocities, friction, damping, a
/// non-zero quaternion, and for a dynamic body a mass or density and a valid inertia.
void check_body_desc(const ShapeDictionary& shapes, const BodyDesc& d, bool is_static, const std::string& who);

/// A body state: finite, with a non-zero quaternion.
void check_body_state(const BodyState& s, const std::string& who);

/// An impulse and the world point it acts at: finite.
void check_impulse(const float impulse[3], const float point[3], const std::string& who);

/// q scaled to unit length into `out`; a warning for `who` when it was not unit already. The
/// caller has checked that q is not zero.
void normalise_orientation(const float q[4], float out[4], const std::string& who, std::vector<std::string>& warnings);

/// The force table entry of `type`: refuses an unknown type (listing the known ones) and a
/// global one (set in the settings).
const gen::ForceInfo& force_type_info(const std::string& type);

/// Writes each named parameter into a force's packed instance: refuses unknown names, a wrong
/// number of values, non-finite values and values below the descriptor's minimum.
void set_force_params(const gen::ForceInfo& info, const ForceParams& params, std::vector<unsigned char>& instance);

}  // namespace cellphys::ppe
