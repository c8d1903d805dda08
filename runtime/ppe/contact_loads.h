// What each contact carries under gravity: a body's weight and everything resting on it pass
// down through the contacts that hold it up, top to bottom, so a light box under a heavy one
// (or at the foot of a stack) gets contacts stiff enough for the weight above it. Computed
// from this step's contacts alone: no feedback from how far a contact sank, which, tried
// first, made a pile's contacts stiffen and soften in turn until it was thrown apart.
#pragma once
#include <vector>

#include "runtime/ppe/body_records.h"

namespace cellphys::ppe {

struct WorldSettings;

/// Sets each contact's load: the mass whose soft spring, at the contact frequency, sinks by
/// contact_load_depth under the weight the contact carries (0 without gravity). A body no contact
/// holds up hands its weight down its joints to the bodies below it.
void carry_loads(const std::vector<WorldBody>& bodies, const std::vector<WorldForce>& forces, const WorldSettings& s,
                 std::vector<WorldContact>& contacts);

/// How much gravity alone closes a contact of normal n (from a to b) in a step (m/s, 0 or less):
/// the upper body falls onto what holds it. Against static geometry the fall is signed (a ball
/// thrown up at a ceiling falls away from it); between two bodies the lower one is taken to rest
/// on something, so the upper falls onto it. The contact acts in a step only if its gap closes
/// by the step's end with this fall (codegen/descriptors/forces/contact.yaml).
float gravity_fall(const float n[3], bool against_static, const WorldSettings& s);

}  // namespace cellphys::ppe
