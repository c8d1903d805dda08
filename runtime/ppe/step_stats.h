// What one step did, stage by stage (the stages are listed in runtime/ppe/world.h).
#pragma once
#include <chrono>
#include <cstddef>
#include <cstdint>

namespace cellphys::ppe {

/// Wall time of each stage of one step, in milliseconds, under the stage's name.
struct StageTimes {
  double broad_ms = 0, mid_ms = 0, narrow_ms = 0;  // 1. collide
  double wake_ms = 0;                              // 2. wake touched groups
  double push_ms = 0;                              // 3. push deep overlap out
  double islands_ms = 0;                           // 4. build islands
  double decouple_ms = 0;                          // 5. decouple
  // 6. integrate islands: pack, run and check (integrate_ms), unpack. On the world's own threads a
  // thread packs, steps and unpacks the islands it takes: all of it is integrate_ms then.
  double pack_ms = 0, integrate_ms = 0, unpack_ms = 0;
  double sleep_ms = 0;                             // 7. put quiet islands to sleep
  double events_ms = 0;                            // 8. contact and sensor events
  double total_ms = 0;
};

/// Every entry of StageTimes with its name, in step order: reports list the stages from it.
struct StageTimeField {
  const char* name;
  double StageTimes::*ms;
};
inline constexpr StageTimeField kStageTimeFields[] = {
    {"broad", &StageTimes::broad_ms},       {"mid", &StageTimes::mid_ms},
    {"narrow", &StageTimes::narrow_ms},     {"wake", &StageTimes::wake_ms},
    {"push", &StageTimes::push_ms},         {"islands", &StageTimes::islands_ms},   {"decouple", &StageTimes::decouple_ms},
    {"pack", &StageTimes::pack_ms},         {"integrate", &StageTimes::integrate_ms},
    {"unpack", &StageTimes::unpack_ms},     {"sleep", &StageTimes::sleep_ms},
    {"events", &StageTimes::events_ms},
    {"total", &StageTimes::total_ms},
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
  // One-body islands touching only the world that were stepped several to an image (on the
  // world's own threads: runtime/ppe/step_integrate.cpp).
  uint32_t shared_islands = 0;
  uint32_t woken = 0, fell_asleep = 0;
  uint32_t pushed_bodies = 0;  // moved out of deep overlap by the push stage
  uint32_t projected_joints = 0;  // joints moved back within joint.projection after the solve (first pass)
  size_t local_store_peak_bytes = 0;
  // Islands whose result came back unsound (size, checksum, header, or refused by a node
  // that was sent a sound image) and were recomputed on this process.
  uint32_t recomputed_islands = 0;
  // Transport (runtime/ppe/island_runner.h), summed over the step's waves and sweeps:
  // message bytes each way on the runner's wire (0 for the in-process worker pool).
  uint64_t bytes_to_nodes = 0, bytes_from_nodes = 0;
  uint32_t messages = 0, bad_messages = 0, reassigned_islands = 0, dropped_nodes = 0;
  // The same islands in the reference design's wire tables (docs/distributed.md), whatever the runner:
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
  // Where the last stage timed in this step ended (World::step sets it at its start; unset, a
  // stage times from its own start): the next stage starts there.
  std::chrono::steady_clock::time_point stage_end{};
};

/// Adds a stage's wall time to one StageTimes entry: from the end of the stage timed before it
/// in the step (or the step's start) to its own end. The clock is read once a stage: two reads
/// a stage, at ~30 ns each under a virtual machine's clock, were a third of a one-body step.
/// Outside a step (stage_end unset) it reads the clock at its start too.
class StageTimer {
 public:
  StageTimer(StepStats& st, double StageTimes::*ms)
      : end_(st.stage_end),
        ms_(st.times.*ms),
        start_(end_ != std::chrono::steady_clock::time_point{} ? end_ : std::chrono::steady_clock::now()) {}
  ~StageTimer() {
    end_ = std::chrono::steady_clock::now();
    ms_ += std::chrono::duration<double, std::milli>(end_ - start_).count();
  }
  StageTimer(const StageTimer&) = delete;
  StageTimer& operator=(const StageTimer&) = delete;

 private:
  std::chrono::steady_clock::time_point& end_;
  double& ms_;
  std::chrono::steady_clock::time_point start_;
};

}  // namespace cellphys::ppe
