// Evaluates the generated force kernels over a packed island, a batch of instances at a
// time (one instance per SIMD lane), and scatters what the caller asks for: the forces,
// the Jacobian blocks of the implicit system, or a Jacobian-times-vector product.
// Only the force types present in the island are visited.
#pragma once
#include <cstddef>
#include <cstdint>

#include "runtime/spu/island_image.h"

namespace cellphys::spu {

/// Off-diagonal block positions of the system matrix (block_sparse.h's row layout).
struct BlockStructure {
  int n = 0;
  int nnz = 0;
  int32_t* row_start = nullptr;  // n + 1
  int32_t* col = nullptr;        // nnz
  int find(int row, int column) const;  // index of block (row, column), -1 if absent
};

struct ForceTargets {
  float* forces = nullptr;  // n * 8: F_i accumulated (padded)
  // Implicit assembly (optional): `forces` then receives g_i = F_i + h dF_i/ddelta_j u_j (u the
  // bodies' velocities) and K_ij = h dF_i/du_j + h^2 dF_i/ddelta_j goes into the blocks.
  float* diag_k = nullptr;     // n * 48: K_ii
  float* offdiag_k = nullptr;  // nnz * 48: K_ij
  const BlockStructure* structure = nullptr;
  // The step the forces are evaluated for: the implicit form's h, and the `h` a descriptor
  // may read (a contact that will close within the step acts from its start).
  float h = 0.0f;
  // Jacobian product, optional: jv_out_i += dF_i/ddelta_j jv_in_j
  const float* jv_in = nullptr;
  float* jv_out = nullptr;
  uint32_t skip_types = 0;  // bit t set: force type t is not evaluated
  const float* ref = nullptr;  // n * 8: reference poses (x y z _ w x y z) of contact geometry
};

/// Bytes of scratch evaluate_forces needs (one batch of inputs and outputs) for an island
/// holding the force types whose bits `types` sets: a joint type an island does not hold
/// costs it no local store.
size_t force_scratch_bytes(uint32_t types);

/// Accumulates into the targets (the caller zeroes them). Jacobians are evaluated only when
/// a target needs them; otherwise the kernels' F-only entry points run.
void evaluate_forces(const IslandView& island, const ForceTargets& t, float* scratch);

/// One island's share of a pass over several: its image and its targets.
struct ForceJob {
  const IslandView* v = nullptr;
  const ForceTargets* t = nullptr;
};

/// evaluate_forces over several islands at once, a one-body kernel's SIMD lanes filled across
/// islands (many small islands fill a batch together instead of one each). Every job's
/// targets ask for the same thing at the same h, and each island's sections ascend by force
/// type, as IslandBuilder writes them. Each island's targets receive exactly what
/// evaluate_forces gives it alone, to the bit: its bodies' contributions are added in the same
/// order. Scratch: force_scratch_bytes of the union of the islands' force types.
void evaluate_forces_together(const ForceJob* jobs, int count, float* scratch);

}  // namespace cellphys::spu
