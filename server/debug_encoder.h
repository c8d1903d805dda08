// The debug message (protocol::Debug): what the solver did in the last step, for a viewer's
// overlays — every dynamic body's island and mass, the contacts with their normal force, and the
// couplings decoupling cut.
#pragma once
#include <cstdint>
#include <vector>

#include "runtime/ppe/world.h"

namespace cellphys::server {

std::vector<unsigned char> encode_debug(const ppe::World& w, uint32_t epoch);

}  // namespace cellphys::server
