// Block-row sparse matrix times vector and the padded-vector operations the solvers use.
#include "runtime/spu/block_sparse.h"

#include "cellphys/gen/block_ops.h"
#include "runtime/spu/simd.h"

namespace cellphys::spu {

using simd::load;
using simd::splats;
using simd::store;
using simd::vf8;

static_assert(kBlockFloats == gen::kBlockFloats && kVecFloats == gen::kVecFloats,
              "block_sparse.h and the generated block ops must agree on the layout");

// The seed's mul(): one pass over block rows, each row's sum started from the diagonal term
// and accumulated over the row's blocks in storage order, so the result depends on the data
// and the storage order only.
void spmv(const BlockRowMatrix& A, const float* x, float* y) {
  for (int i = 0; i < A.n; ++i) {
    const float* xi = x + kVecFloats * i;
    float* yi = y + kVecFloats * i;
    if (A.unit_diagonal)
      store(yi, load<vf8>(xi));
    else
      gen::block_mul(A.diag + kBlockFloats * i, xi, yi);
    for (int32_t k = A.row_start[i]; k < A.row_start[i + 1]; ++k)
      gen::block_mul_add(A.blocks + kBlockFloats * k, x + kVecFloats * A.col[k], yi);
  }
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
