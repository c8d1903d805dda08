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
/// With a sharer, a system of kShareBlocks blocks or more has its rows shared out (each row
/// gets the bits it gets alone).
bool scale_system(const BlockStructure& s, const gen::W_Element* w, float h, float* diag_k, float* offdiag_k,
                  float* rhs, float* p_out, RowSharer* sharer = nullptr);

/// The split scale_system makes, for callers that invert several islands' diagonal blocks in
/// one pass: diag_k's blocks become A_ii = I - W_i K_ii in place (n of them) ...
void form_diagonal(int n, const gen::W_Element* w, float* diag_k);

/// ... each block becomes its inverse in place, eight at a time in SIMD lanes (blocks of any
/// islands: each gets the bits it would alone), a block the straight-line inverse refuses by
/// pivoting, and *failed is set for one that cannot be inverted ...
class BlockInverter {
 public:
  void add(float* block, bool* failed);
  void flush();  // the last, partial group

 private:
  float* blocks_[8] = {};
  bool* failed_[8] = {};
  int n_ = 0;
};
/// (all of `blocks`: false if one cannot be inverted) ...
bool invert_blocks(float* const* blocks, int count);

/// ... and the rows are scaled by them: what scale_system does after its inverses.
void scale_inverted(const BlockStructure& s, const gen::W_Element* w, float h, const float* dinv, float* offdiag_k,
                    float* rhs, float* p_out);

/// b̂_i = P_i g_i for a later right-hand side in force units (Rosenbrock's second stage).
void scale_rhs(int n, const float* p, const float* g, float* out);

BlockRowMatrix matrix_of(const BlockStructure& s, const float* blocks);

}  // namespace cellphys::spu
