// The local-store layout of one island's integration: what each integrator allocates, and
// the byte accounting that decides, before any work, whether an island fits.
#pragma once
#include <cstddef>
#include <cstdint>

#include "runtime/spu/force_eval.h"
#include "runtime/spu/island_image.h"
#include "runtime/spu/krylov.h"
#include "runtime/spu/local_store.h"

namespace cellphys::spu {

/// What the accounting needs to know of an island (all in its header and section table).
struct IslandCounts {
  uint32_t num_bodies = 0;
  uint32_t num_blocks = 0;      // distinct off-diagonal blocks
  uint32_t pair_instances = 0;  // binary instances between two bodies
  uint32_t image_bytes = 0;     // the packed island
  Integrator integrator = Integrator::implicit_split;
  Solver solver = Solver::cgs;
  uint32_t force_types = ~0u;   // a bit per force type the island holds (scratch fits their kernels)
};
IslandCounts counts_of(const IslandView& v);

/// Bytes per region; `total` is what must fit the local store (double buffers included).
struct Footprint {
  RegionBytes bytes{};
  size_t total = 0;
};
Footprint footprint(const IslandCounts& c);

/// Pointers into the local store for one island's integration (null where unused).
struct Workspace {
  int n = 0;
  gen::W_Element* w = nullptr;
  BlockStructure structure;
  float* blocks = nullptr;   // nnz * 48
  float* forces = nullptr;   // n * 8: F, g, then b̂
  float* x = nullptr;        // n * 8: solution
  float* u0 = nullptr;       // n * 8: start velocities, then new rotation state
  float* ref = nullptr;      // n * 8: the island's start poses, where its contacts were measured
  float* saved = nullptr;    // n * 16: state at step start (integrators that move bodies in stages)
  float* k1 = nullptr;       // n * 8 (Rosenbrock first stage; RK4 force accumulator)
  float* jv = nullptr;       // n * 8 (Rosenbrock Jacobian product)
  float* acc = nullptr;      // n * 16 (RK4 increment accumulator)
  float* p = nullptr;        // n * 48 (Rosenbrock: P_i = D_i^-1 W_i)
  float* diag = nullptr;     // n * 48, phase-shared scratch (assembly)
  float* force_scratch = nullptr;  // phase-shared scratch (assembly)
  float* solver_work = nullptr;    // phase-shared scratch (solve)
  int32_t* pair_scratch = nullptr; // phase-shared scratch (structure build)
  int pair_capacity = 0;
};

/// Allocates the workspace in `ls` (its footprint was checked first).
bool allocate_workspace(LocalStore& ls, const IslandCounts& c, Workspace& ws);
/// The same with footprint(c) given.
bool allocate_workspace(LocalStore& ls, const IslandCounts& c, const Footprint& f, Workspace& ws);

}  // namespace cellphys::spu
