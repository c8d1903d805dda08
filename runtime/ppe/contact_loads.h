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
/// contact_load_depth under the weight the contact carries (0 without gravity).
void carry_loads(const std::vector<WorldBody>& bodies, const WorldSettings& s, std::vector<WorldContact>& contacts);

}  // namespace cellphys::ppe
