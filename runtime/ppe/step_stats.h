// What one step did: the seed's server loop, stage by stage.
#pragma once
#include <cstddef>
#include <cstdint>

namespace cellphys::ppe {

struct StageTimes {
  double broad_ms = 0, mid_ms = 0, narrow_ms = 0, sleep_ms = 0, islands_ms = 0, decouple_ms = 0,
         pack_ms = 0, integrate_ms = 0, unpack_ms = 0, total_ms = 0;
};

struct StepStats {
  uint64_t step = 0;
  uint32_t bodies = 0, static_bodies = 0, active_bodies = 0, sleeping_bodies = 0, outside_region = 0;
  uint32_t broad_phase_boxes = 0;  // dynamic and static boxes kept by the region cull
  uint32_t mid_phase_pairs = 0;    // overlapping boxes after sort and sweep (+ plane pairs)
  uint32_t narrow_phase_pairs = 0; // pairs with at least one contact
  uint32_t contacts = 0;
  uint32_t islands = 0, decoupled_islands = 0, cut_couplings = 0;
  uint32_t decouple_sweeps = 0;  // block Gauss-Seidel sweeps over the parts of split islands
  float decouple_change = 0;     // largest velocity change (m/s) in the last sweep
  uint32_t solver_iterations = 0, solves = 0, step_halvings = 0, failed_islands = 0, substeps = 0;
  uint32_t woken = 0, fell_asleep = 0;
  size_t local_store_peak_bytes = 0;
  StageTimes times;
};

}  // namespace cellphys::ppe
