// Builds the island's linear system in the local store: the block structure from the pair
// forces, then A = I - W K (K = h dF/du + h^2 dF/ddelta, accumulated by force_eval) and
// b = h W g (g = F + h dF/ddelta u0), scaled block-row by block-row by D^-1 = A_ii^-1 so the
// stored matrix has identity diagonal blocks (block_sparse.h).
#pragma once
#include <cstdint>

#include "runtime/spu/block_sparse.h"
#include "runtime/spu/force_eval.h"

namespace cellphys::spu {

/// Fills s.row_start / s.col (caller-allocated: n + 1 and header.num_blocks entries) from
/// the pair instances; `pairs` is scratch of 2 * num_blocks... (2 int32 per pair instance).
/// Returns false when the island's num_blocks does not match.
bool build_structure(const IslandView& v, BlockStructure& s, int32_t* pair_scratch, int pair_scratch_capacity);

/// Pair instances of every binary section (the scratch build_structure needs: 2 per pair, int32 each x2).
int count_pair_instances(const IslandView& v);

/// In place: diag_k (n blocks, destroyed), offdiag_k (K_ij -> Â_ij), rhs (g -> b̂).
/// If p_out is given, P_i = D_i^-1 W_i is kept (n blocks) for scaling later right-hand sides.
/// Returns false if a diagonal block cannot be inverted.
bool scale_system(const BlockStructure& s, const gen::W_Element* w, float h, float* diag_k, float* offdiag_k,
                  float* rhs, float* p_out);

/// b̂_i = P_i g_i for a later right-hand side in force units (Rosenbrock's second stage).
void scale_rhs(int n, const float* p, const float* g, float* out);

BlockRowMatrix matrix_of(const BlockStructure& s, const float* blocks);

}  // namespace cellphys::spu
