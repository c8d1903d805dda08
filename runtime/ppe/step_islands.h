// Stage 4 of the step: awake bodies partitioned into islands, the groups that contacts and
// binary forces join; static bodies and the world join nothing.
#pragma once
#include <vector>

#include "runtime/ppe/body_records.h"
#include "runtime/ppe/body_sets.h"
#include "runtime/ppe/island_packer.h"
#include "runtime/ppe/step_stats.h"

namespace cellphys::ppe {

/// What the stage reuses: per body slot, set for the awake bodies alone each step.
struct IslandScratch {
  std::vector<uint32_t> parent;
  std::vector<int32_t> island_of;
};

/// The islands of the awake bodies, each with its bodies (ascending), the contacts and the
/// forces acting on them; numbered by their smallest body, so the order does not depend on the
/// order of the couplings. Counts bodies (live, static, active, sleeping), islands, contacts.
/// `islands` is replaced; the storage of its entries is reused.
void build_islands(const std::vector<WorldBody>& bodies, const std::vector<WorldForce>& forces,
                   const std::vector<WorldContact>& contacts, const AwakeBodies& awake, IslandScratch& scratch,
                   StepStats& st, std::vector<IslandContent>& islands);

}  // namespace cellphys::ppe
