// Stage 6 of the step: every island integrated on the compute kernels. Per wave: pack the
// islands' parts into images, run them on the island runner, check every result (an unsound
// one is computed again here), unpack. Wave k holds part k of every island, so the parts of a
// split island run in order, each from the start state against ghosts at the latest
// velocities of the others: one block Gauss-Seidel sweep. Split islands sweep again until no
// velocity changes by more than the decoupling tolerance. Step-size halving happens inside
// the kernel; an island whose step still fails keeps its start state and is counted.
#pragma once
#include <functional>
#include <vector>

#include "runtime/ppe/body_records.h"
#include "runtime/ppe/island_runner.h"
#include "runtime/ppe/step_decouple.h"
#include "runtime/ppe/step_stats.h"

namespace cellphys::ppe {

struct WorldSettings;

/// Where islands are computed: the runner, and the worker that recomputes a result that came
/// back unsound. Each is asked for only when needed (a step with no islands starts no
/// workers; the local worker's store is allocated only for a result that came back unsound).
struct IslandCompute {
  std::function<IslandRunner&()> runner;
  std::function<spu::ComputeWorker&()> local;
};

/// Advances the bodies of every island by one step of s.dt. Returns, per island, whether its
/// step failed (its bodies kept their start state).
std::vector<uint8_t> integrate_islands(const WorldSettings& s, const ShapeDictionary& shapes, const std::vector<IslandContent>& islands,
                       const DecoupledIslands& parts, const std::vector<WorldForce>& forces,
                       const std::vector<WorldContact>& contacts, std::vector<WorldBody>& bodies, const IslandCompute& compute,
                       StepStats& st);

}  // namespace cellphys::ppe
