// The island's system matrix in the reference design's shape: 6x6 logical blocks stored as padded 8x6
// column-major floats, off-diagonal blocks grouped per block row with their column index,
// vectors padded to 8 floats per body (x y z _ x y z _).
//
// One departure from the reference design, measured and kept: the matrix is stored block-Jacobi scaled,
// Â = D^-1 A with D = diag(A_ii), so every diagonal block is the identity and is not
// stored. It is the reference design's block-Jacobi preconditioner applied once, on the left, at
// assembly; it saves the diagonal blocks and their inverses in the local store (25 KiB for
// the reference design's 65-body island) and the preconditioner solve in every iteration.
#pragma once
#include <cstdint>

#include "runtime/spu/row_sharing.h"

namespace cellphys::spu {

inline constexpr int kBlockFloats = 48;  // 8 x 6
inline constexpr int kVecFloats = 8;     // one body's padded 6-vector

struct BlockRowMatrix {
  int n = 0;                          // block rows = bodies
  const int32_t* row_start = nullptr;  // n + 1 entries; row i's blocks are [row_start[i], row_start[i+1])
  const int32_t* col = nullptr;        // column (body) of each off-diagonal block
  const float* blocks = nullptr;       // kBlockFloats per off-diagonal block, 32-byte aligned
  // unit_diagonal: the diagonal is I and not stored (the scaled system). Otherwise `diag`
  // holds n diagonal blocks (used by tests and by the unscaled reference path).
  bool unit_diagonal = true;
  const float* diag = nullptr;
};

/// y = A x. x and y hold n * kVecFloats floats, 32-byte aligned, and must not alias.
/// With a sharer, a matrix of kShareBlocks blocks or more has its rows shared out (each row
/// is computed as alone: the same bits).
void spmv(const BlockRowMatrix& A, const float* x, float* y, RowSharer* sharer = nullptr);
inline constexpr int kShareBlocks = 4096;

// Vector operations on padded block vectors (n * kVecFloats floats, padding lanes zero).
// Reductions use a fixed order, so one build gives the same bits every run.
float dot(int n, const float* a, const float* b);
void axpy(int n, float alpha, const float* x, float* y);           // y += alpha x
void xpby(int n, const float* x, float beta, float* y);            // y = x + beta y
void copy(int n, const float* x, float* y);
void zero(int n, float* y);

}  // namespace cellphys::spu
