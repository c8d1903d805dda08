// Stage 5 of the step: islands too big for a local store, and for what the runner computes
// whole (IslandRunner::whole_island_bytes), are cut in space into parts that fit.
// A coupling the cut crosses goes into both parts, each of which holds the body across the cut
// as a ghost, so both sides stay implicit in the coupling; the parts of a split island are
// integrated in order, one part per wave (runtime/ppe/step_integrate.h).
#pragma once
#include <cstddef>
#include <cstdint>
#include <vector>

#include "runtime/ppe/island_packer.h"
#include "runtime/ppe/step_stats.h"

namespace cellphys::ppe {

/// What cutting islands reuses from step to step, so a warm step cuts without allocating: the
/// two halves of a cut at each depth, and the bodies' order along a cut.
struct CutScratch {
  static constexpr size_t kMaxDepth = 64;
  std::vector<IslandContent> halves;  // 2 per depth
  std::vector<uint64_t> keys;         // (position along the cut, place in the island)
};

/// The parts of an island that each fit the local store, in the order they are integrated, into
/// `parts` (its storage reused); counts the couplings cut. Returns how many, or 0 when the island
/// fits whole: it is then integrated as it is, and `parts` is left as it was. Integrating the
/// parts in order, each holding the bodies across its cuts as kinematic ghosts at their latest
/// velocities, is one block Gauss-Seidel sweep on the island's linear system; sweeps repeat
/// until the velocities settle (integrate_islands), so the parts converge on the whole island's
/// step. An island fits when its footprint is at most `fit` bytes (the local store, or more
/// when the runner computes big islands whole); a part always fits the local store.
/// `scratch` and `probe` are the fit test's packing.
size_t decouple(const PackContext& pc, const IslandContent& island, size_t fit, uint32_t& cut_couplings,
                PackScratch& scratch, PackedIsland& probe, CutScratch& cuts, std::vector<IslandContent>& parts);

/// Every island's parts. An island that fits whole is not copied into parts (a copy of every
/// island's lists was most of the stage in a world of small islands): part(k, 0) is the island.
struct DecoupledIslands {
  const std::vector<IslandContent>* islands = nullptr;  // the islands decoupled (they outlive the step)
  std::vector<std::vector<IslandContent>> parts;        // per split island: its parts in integration order
  std::vector<size_t> used;                             // per island: its parts, 0 when whole
  size_t waves = 0;                                     // the most parts of any island
  bool split() const { return waves > 1; }
  size_t count(size_t k) const { return used[k] ? used[k] : 1; }
  bool is_split(size_t k) const { return used[k] > 1; }
  const IslandContent& part(size_t k, size_t wave) const { return used[k] ? parts[k][wave] : (*islands)[k]; }
  PackedIsland probe;                                   // the fit test's packing, reused
  CutScratch cuts;                                      // the cuts', reused
};

/// The parts of every island into `d` (replaced; its storage is reused); counts decoupled
/// islands and cut couplings. `whole_bytes`: the runner's IslandRunner::whole_island_bytes().
void decouple_islands(const PackContext& pc, const std::vector<IslandContent>& islands, size_t whole_bytes,
                      StepStats& st, PackScratch& scratch, DecoupledIslands& d);

}  // namespace cellphys::ppe
