// Islands shared by the tests and the benchmarks: the reference group (65 bodies,
// 400 contacts, 199 non-zero blocks) and small closed-form set-ups.
#pragma once
#include <vector>

#include <algorithm>

#include "runtime/spu/island_image.h"

namespace cellphys::testing {

/// A box of half-extents (hx, hy, hz) and mass m at rest at the origin, identity orientation.
gen::Rigid_Body_Fields box_body(float m, float hx, float hy, float hz);

/// The reference group: 65 boxes (half-extent 0.25 m, 1 kg) in two layers on the
/// ground: 33 on the ground in 3 rows of 11, 32 on top (30 bridging two lower boxes, 2 on
/// one), 5 side contacts between upper boxes. Four contact points per touching pair:
/// 132 with the ground, 268 between bodies: 400 contacts, 67 coupled pairs, so
/// 65 + 2 x 67 = 199 non-zero blocks. Gravity on; 1 mm penetrations.
void build_reference_island(spu::IslandBuilder& b);

}  // namespace cellphys::testing
