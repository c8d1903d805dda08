// The forces' globals in WorldSettings (WorldSettings::globals), as the force descriptors
// declare them: gen::kGlobalTable gives each one's name, bounds, default and place in a scene
// file, so the World, the scene reader and snapshots handle a new force's global unchanged.
#pragma once
#include <string>

#include "runtime/ppe/world.h"

namespace cellphys::ppe {

/// The lanes (1 or 3 floats) of global g in a world's settings.
float* global_lanes(gen::Force_Globals& globals, const gen::GlobalInfo& g);
const float* global_lanes(const gen::Force_Globals& globals, const gen::GlobalInfo& g);

/// Why v cannot be a lane of global g ("" when it can): it must be finite and within g's bound.
std::string global_problem(const gen::GlobalInfo& g, float v);

/// Throws WorldError("settings.NAME: REASON") for the first setting out of its bounds.
void validate_settings(const WorldSettings& s);

}  // namespace cellphys::ppe
