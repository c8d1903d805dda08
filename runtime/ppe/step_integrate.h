// Stage 6 of the step: every island integrated on the compute kernels. Per wave: pack the
// islands' parts into images, run them on the island runner, check every result (an unsound
// one is computed again here), unpack; on the world's own threads each thread packs, steps and
// unpacks the parts it takes, in its own core's cache. Wave k holds part k of every island, so
// the parts of a split island run in order, each from the start state against ghosts at the latest
// velocities of the others: one block Gauss-Seidel sweep. Split islands sweep again until no
// velocity changes by more than the decoupling tolerance. Step-size halving happens inside
// the kernel; an island whose step still fails keeps its start pose, is stopped (given back
// moving, it failed again from the same state every step) and is counted.
#pragma once
#include <functional>
#include <utility>
#include <vector>

#include "runtime/ppe/body_records.h"
#include "runtime/ppe/island_runner.h"
#include "runtime/ppe/step_decouple.h"
#include "runtime/ppe/step_stats.h"
#include "runtime/ppe/worker_pool.h"

namespace cellphys::ppe {

struct WorldSettings;

/// Where islands are computed: the runner, and the worker that recomputes a result that came
/// back unsound. Each is asked for only when needed (a step with no islands starts no
/// workers; the local worker's store is allocated only for a result that came back unsound).
struct IslandCompute {
  std::function<IslandRunner&()> runner;
  std::function<spu::ComputeWorker&()> local;
  WorkerPool* threads = nullptr;  // the world's threads, which pack the islands (null: packed here)
};

/// What a thread of the world's pool keeps while it packs and steps a run of parts: the images
/// it steps (lone parts merged, runtime/ppe/step_integrate.cpp) and the parts each holds.
struct ThreadShares {
  struct Group {
    size_t first, end;  // the run's jobs [first, end) the image holds
    size_t shared;      // its index in `images` when it holds several (one part: its own slot)
  };
  IslandContent merged;
  // The shared images, reused by any run this thread takes: the parts a run merges change from
  // step to step as contacts come and go, so a part's own slot would be regrown each step.
  std::vector<PackedIsland> images;
  std::vector<Group> groups;
  std::vector<spu::IslandJob> jobs;
  std::vector<spu::IslandReport> reports;
  void reserve(size_t images) {
    merged.bodies.reserve(images), groups.reserve(images), jobs.reserve(images), reports.reserve(images);
  }
};

/// What the stage reuses from step to step (the world keeps one): a warm step packs and runs
/// its islands without allocating.
struct IntegrateScratch {
  PackScratch pack;
  std::vector<PackScratch> thread_pack;    // one a thread, when the threads pack
  std::vector<const IslandContent*> todo;  // this wave's parts
  std::vector<PackedIsland> packed;  // the first `used` are this wave's
  std::vector<size_t> island_of_packed, order;
  std::vector<uint64_t> order_keys, sort_buffer;  // for `order`: (size rank, index) keys
  std::vector<spu::IslandJob> jobs;       // job j is packed[order[j]]
  std::vector<spu::IslandReport> reports;
  std::vector<std::pair<size_t, size_t>> runs;  // on the world's threads: [first, end) jobs a thread takes
  std::vector<uint8_t> unpacked;           // per job: unpacked where it was stepped
  std::vector<ThreadShares> threads;       // per thread, on the world's own threads
  std::vector<StepStats> thread_stats;     // per thread: the wire tables of the islands it packed
  std::vector<WorldBody> start;           // the start state, when an island is split
  std::vector<float> before, after;       // split islands' velocities around a sweep
  std::vector<uint8_t> part_failed;
};

/// Advances the bodies of every island by one step of s.dt. Sets, per island, whether its
/// step failed (its bodies kept their start pose, their velocities zeroed) in `failed` (replaced).
void integrate_islands(const WorldSettings& s, const ShapeDictionary& shapes, const std::vector<IslandContent>& islands,
                       const DecoupledIslands& parts, const std::vector<WorldForce>& forces,
                       const std::vector<WorldContact>& contacts, std::vector<WorldBody>& bodies, const IslandCompute& compute,
                       IntegrateScratch& scratch, std::vector<uint8_t>& failed, StepStats& st);

}  // namespace cellphys::ppe
