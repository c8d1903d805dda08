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
  // Islands whose result came back unsound (size, checksum, header, or refused by a node
  // that was sent a sound image) and were recomputed on this process.
  uint32_t recomputed_islands = 0;
  // Transport (runtime/ppe/island_runner.h), summed over the step's waves and sweeps:
  // message bytes each way on the runner's wire (0 for the in-process worker pool).
  uint64_t bytes_to_nodes = 0, bytes_from_nodes = 0;
  uint32_t messages = 0, bad_messages = 0, reassigned_islands = 0, dropped_nodes = 0;
  // The same islands in the seed's wire tables (docs/distributed.md), whatever the runner:
  // bodies out (ghosts included) at 22 floats plus their shape's geometry, or at 25 floats
  // with a dictionary reference; 13 floats per body back. Each island's header, force and
  // contact records are counted in both outbound forms (island_bytes_shared).
  uint64_t island_bodies = 0;
  uint64_t island_bytes_shared = 0;    // header, sections, parameters, force and contact records
  uint64_t wire_table_to_nodes = 0;    // 22 floats + geometry per body, plus the shared bytes
  uint64_t wire_table_to_nodes_compressed = 0;  // 25 floats per body, plus the shared bytes
  uint64_t wire_table_from_nodes = 0;  // 13 floats per body
  uint64_t image_bytes = 0, result_bytes = 0;  // packed images and kernel results, as in memory
  StageTimes times;
};

}  // namespace cellphys::ppe
