// Block-row sparse matrix times vector and the padded-vector operations the solvers use.
#include "runtime/spu/block_sparse.h"

#include "cellphys/gen/block_ops.h"
#include "runtime/base/simd.h"

namespace cellphys::spu {

using simd::load;
using simd::splats;
using simd::store;
using simd::vf8;

static_assert(kBlockFloats == gen::kBlockFloats && kVecFloats == gen::kVecFloats,
              "block_sparse.h and the generated block ops must agree on the layout");

namespace {

// The reference design's mul() over rows [begin, end): each row's sum started from the diagonal
// term and accumulated over the row's blocks in storage order, so the result depends on the
// data and the storage order only. The row sum lives in a local and A's fields in locals:
// the SIMD stores may alias anything, and would otherwise force reloads after every block.
void spmv_rows(const BlockRowMatrix& A, const float* x, float* y, int begin, int end) {
  const int32_t* const row_start = A.row_start;
  const int32_t* const col = A.col;
  const float* const blocks = A.blocks;
  const float* const diag = A.unit_diagonal ? nullptr : A.diag;
  for (int i = begin; i < end; ++i) {
    const float* xi = x + kVecFloats * i;
    alignas(32) float sum[kVecFloats];
    if (diag)
      gen::block_mul(diag + kBlockFloats * i, xi, sum);
    else
      store(sum, load<vf8>(xi));
    for (int32_t k = row_start[i]; k < row_start[i + 1]; ++k)
      gen::block_mul_add(blocks + kBlockFloats * k, x + kVecFloats * col[k], sum);
    store(y + kVecFloats * i, load<vf8>(sum));
  }
}

struct SpmvRange {
  const BlockRowMatrix* A;
  const float* x;
  float* y;
};

// Rows a shared range takes: a few microseconds of blocks, against the ~100 ns of taking one.
constexpr size_t kShareRows = 128;

}  // namespace

void spmv(const BlockRowMatrix& A, const float* x, float* y, RowSharer* sharer) {
  if (!sharer || A.n <= 0 || A.row_start[A.n] - A.row_start[0] < kShareBlocks) return spmv_rows(A, x, y, 0, A.n);
  SpmvRange range{&A, x, y};
  sharer->share(static_cast<size_t>(A.n), kShareRows, [](void* c, size_t begin, size_t end) {
    const SpmvRange& r = *static_cast<const SpmvRange*>(c);
    spmv_rows(*r.A, r.x, r.y, static_cast<int>(begin), static_cast<int>(end));
  }, &range);
}

// One vf8 of partial sums carried across bodies in order, then hsum's fixed lane order:
// the summation order depends on n alone.
float dot(int n, const float* a, const float* b) {
  vf8 acc = splats<vf8>(0.0f);
  for (int i = 0; i < n; ++i)
    acc = simd::madd(load<vf8>(a + kVecFloats * i), load<vf8>(b + kVecFloats * i), acc);
  return simd::hsum(acc);
}

void axpy(int n, float alpha, const float* x, float* y) {
  const vf8 a = splats<vf8>(alpha);
  for (int i = 0; i < n; ++i) {
    float* yi = y + kVecFloats * i;
    store(yi, simd::madd(a, load<vf8>(x + kVecFloats * i), load<vf8>(yi)));
  }
}

void xpby(int n, const float* x, float beta, float* y) {
  const vf8 b = splats<vf8>(beta);
  for (int i = 0; i < n; ++i) {
    float* yi = y + kVecFloats * i;
    store(yi, simd::madd(b, load<vf8>(yi), load<vf8>(x + kVecFloats * i)));
  }
}

void copy(int n, const float* x, float* y) {
  for (int i = 0; i < n; ++i) store(y + kVecFloats * i, load<vf8>(x + kVecFloats * i));
}

void zero(int n, float* y) {
  const vf8 z = splats<vf8>(0.0f);
  for (int i = 0; i < n; ++i) store(y + kVecFloats * i, z);
}

}  // namespace cellphys::spu
