// Overlap deeper than contact_hold_depth (bodies spawned or teleported into each other) is
// pushed out before the island's step by moving the bodies apart along the contact normals,
// at most contact_push_speed x h per contact in a step, shared by inverse mass. Velocities
// are untouched: a column spawned into itself unfolds without being thrown. (Box2D's soft
// step separates with a bias velocity that its relax pass then removes; Bullet's split
// impulse moves positions apart the same way.) The contact spring acts on the hold depth only.
#pragma once
#include "runtime/spu/island_image.h"

namespace cellphys::spu {

/// Moves the island's bodies out of deep overlap for a step of h and brings each contact's
/// point and penetration to the moved poses. `scratch` holds 4 floats per body.
void push_out_overlaps(const IslandView& v, float h, float* scratch);

}  // namespace cellphys::spu
