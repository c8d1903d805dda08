// Stage 4 of the step: islands too big for a local store are cut into parts (decouple() in
// runtime/ppe/island_packer.h); the parts of a split island are integrated in order, one part
// per wave.
#pragma once
#include <cstddef>
#include <vector>

#include "runtime/ppe/island_packer.h"
#include "runtime/ppe/step_stats.h"

namespace cellphys::ppe {

struct DecoupledIslands {
  std::vector<std::vector<IslandContent>> parts;  // per island: its parts in integration order
  size_t waves = 0;                               // the most parts of any island
  bool split() const { return waves > 1; }
};

/// The parts of every island; counts decoupled islands and cut couplings.
DecoupledIslands decouple_islands(const PackContext& pc, const std::vector<IslandContent>& islands, StepStats& st);

}  // namespace cellphys::ppe
