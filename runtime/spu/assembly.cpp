#include "runtime/spu/assembly.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>

#include "cellphys/gen/block_ops.h"

namespace cellphys::spu {

using namespace cellphys::gen;

namespace {

int32_t read_i32(const unsigned char* p) {
  int32_t v;
  std::memcpy(&v, p, 4);
  return v;
}

// Gauss-Jordan with partial pivoting: the fallback when the straight-line inverse reports
// a zero or non-finite 3x3 determinant.
bool pivoting_inverse(const float* A, float* Ainv) {
  double m[6][12];
  for (int r = 0; r < 6; ++r)
    for (int c = 0; c < 6; ++c) {
      m[r][c] = A[8 * c + padded(r)];
      m[r][6 + c] = r == c;
    }
  for (int c = 0; c < 6; ++c) {
    int p = c;
    for (int r = c + 1; r < 6; ++r)
      if (std::fabs(m[r][c]) > std::fabs(m[p][c])) p = r;
    if (!(std::fabs(m[p][c]) > 0.0)) return false;
    if (p != c)
      for (int k = 0; k < 12; ++k) std::swap(m[p][k], m[c][k]);
    const double inv = 1.0 / m[c][c];
    for (int k = 0; k < 12; ++k) m[c][k] *= inv;
    for (int r = 0; r < 6; ++r) {
      if (r == c) continue;
      const double f = m[r][c];
      for (int k = 0; k < 12; ++k) m[r][k] -= f * m[c][k];
    }
  }
  block_zero(Ainv);
  for (int r = 0; r < 6; ++r)
    for (int c = 0; c < 6; ++c) Ainv[8 * c + padded(r)] = static_cast<float>(m[r][6 + c]);
  return true;
}

}  // namespace

int count_pair_instances(const IslandView& v) {
  int n = 0;
  for (int s = 0; s < v.num_sections(); ++s) {
    const Island_Section& sec = v.sections[s];
    if (kForceTable[sec.force_type].offset_body_b >= 0) n += static_cast<int>(sec.count - sec.world_count);
  }
  return n;
}

bool build_structure(const IslandView& v, BlockStructure& s, int32_t* pairs, int capacity) {
  // Counting sort of (row, col) both ways for every pair instance, then each row's columns
  // sorted and de-duplicated: ascending columns, independent of instance order. O(pairs).
  const int n = v.num_bodies();
  int32_t* count = s.row_start;  // n + 1, reused as the row cursors
  std::fill(count, count + n + 1, 0);
  int m = 0;
  for (int sidx = 0; sidx < v.num_sections(); ++sidx) {
    const Island_Section& sec = v.sections[sidx];
    const ForceInfo& info = kForceTable[sec.force_type];
    if (info.offset_body_b < 0) continue;
    for (uint32_t k = 0; k < sec.count - sec.world_count; ++k) {
      const unsigned char* inst = v.base + sec.offset + size_t{k} * info.instance_size;
      ++count[read_i32(inst + info.offset_body_a) + 1];
      ++count[read_i32(inst + info.offset_body_b) + 1];
      m += 2;
    }
  }
  if (m > capacity) return false;
  for (int i = 0; i < n; ++i) count[i + 1] += count[i];
  // place: pairs[] holds columns grouped by row; count[i] walks row i's slots
  for (int sidx = 0; sidx < v.num_sections(); ++sidx) {
    const Island_Section& sec = v.sections[sidx];
    const ForceInfo& info = kForceTable[sec.force_type];
    if (info.offset_body_b < 0) continue;
    for (uint32_t k = 0; k < sec.count - sec.world_count; ++k) {
      const unsigned char* inst = v.base + sec.offset + size_t{k} * info.instance_size;
      const int32_t a = read_i32(inst + info.offset_body_a), b = read_i32(inst + info.offset_body_b);
      pairs[count[a]++] = b;
      pairs[count[b]++] = a;
    }
  }
  // count[i] is now the end of row i; rows start at count[i - 1]
  int out = 0, begin = 0;
  for (int row = 0; row < n; ++row) {
    const int end = count[row];
    std::sort(pairs + begin, pairs + end);  // a handful of columns per row
    s.row_start[row] = out;  // safe: row_start[row] (== count[row]) was read above
    for (int k = begin; k < end; ++k)
      if (k == begin || pairs[k] != pairs[k - 1]) {
        if (out >= static_cast<int>(v.header->num_blocks)) return false;
        s.col[out++] = pairs[k];
      }
    begin = end;
  }
  s.row_start[n] = out;
  s.n = n;
  s.nnz = out;
  return out == static_cast<int>(v.header->num_blocks);
}

void form_diagonal(int n, const W_Element* w, float* diag_k) {
  // A_ii = I - W_i K_ii, in place
  for (int i = 0; i < n; ++i) identity_minus_w_mul(w[i].inverse_mass, w[i].inverse_inertia_world, diag_k + kBlockFloats * i);
}

void BlockInverter::add(float* block, bool* failed) {
  blocks_[n_] = block;
  failed_[n_] = failed;
  if (++n_ == 8) flush();
}

void BlockInverter::flush() {
  // the idle lanes of a last, partial group repeat its last block
  if (n_ == 0) return;
  float* group[8];
  for (int l = 0; l < 8; ++l) group[l] = blocks_[std::min(l, n_ - 1)];
  const unsigned done = block_jacobi_inverse8(group, group);
  for (int l = 0; l < n_; ++l)
    if (!(done >> l & 1u) && !pivoting_inverse(group[l], group[l])) *failed_[l] = true;
  n_ = 0;
}

bool invert_blocks(float* const* blocks, int count) {
  bool failed = false;
  BlockInverter inv;
  for (int k = 0; k < count; ++k) inv.add(blocks[k], &failed);
  inv.flush();
  return !failed;
}

namespace {

// Rows [begin, end) of scale_inverted.
void scale_rows(const BlockStructure& s, const W_Element* w, float h, const float* dinv, float* offdiag_k, float* rhs,
                float* p_out, int begin, int end) {
  alignas(32) float W[kBlockFloats], P[kBlockFloats], T[kBlockFloats];
  alignas(32) float g[kVecFloats];
  for (int i = begin; i < end; ++i) {
    const float* Dinv = dinv + kBlockFloats * i;
    // P_i = D_i^-1 W_i; row i of the scaled matrix: Â_ij = -P_i K_ij, b̂_i = h P_i g_i
    block_from_w(w[i].inverse_mass, w[i].inverse_inertia_world, W);
    block_mul_block(Dinv, W, P);
    for (int k = s.row_start[i]; k < s.row_start[i + 1]; ++k) {
      float* B = offdiag_k + kBlockFloats * k;
      block_mul_block(P, B, T);
      block_zero(B);
      block_axpy(-1.0f, T, B);
    }
    float* b = rhs + kVecFloats * i;
    std::memcpy(g, b, sizeof g);
    block_mul(P, g, b);
    for (int r = 0; r < kVecFloats; ++r) b[r] *= h;
    if (p_out) std::memcpy(p_out + kBlockFloats * i, P, sizeof P);
  }
}

// Diagonal blocks [begin, end) formed and inverted; false if one cannot be. `begin` a multiple
// of 8 keeps the inverter's lane groups those of the whole pass (each lane's bits are its
// own block's in any case).
bool invert_diagonal(const W_Element* w, float* diag_k, int begin, int end) {
  form_diagonal(end - begin, w + begin, diag_k + kBlockFloats * begin);
  bool failed = false;
  BlockInverter inv;
  for (int i = begin; i < end; ++i) inv.add(diag_k + kBlockFloats * i, &failed);
  inv.flush();
  return !failed;
}

struct ScaleRange {
  const BlockStructure* s;
  const W_Element* w;
  float h;
  float *diag_k, *offdiag_k, *rhs, *p_out;
  std::atomic<bool> failed{false};
};

// Rows a shared range takes: a multiple of the inverter's 8 lanes.
constexpr size_t kScaleRows = 128;
static_assert(kScaleRows % 8 == 0, "shared ranges start on the inverter's lane groups");

}  // namespace

bool scale_system(const BlockStructure& s, const W_Element* w, float h, float* diag_k, float* offdiag_k, float* rhs,
                  float* p_out, RowSharer* sharer) {
  if (!sharer || s.nnz < kShareBlocks) {
    if (!invert_diagonal(w, diag_k, 0, s.n)) return false;
    scale_rows(s, w, h, diag_k, offdiag_k, rhs, p_out, 0, s.n);
    return true;
  }
  // Every inverse before any row is scaled: a failed one leaves the blocks as the unshared
  // pass leaves them.
  ScaleRange r;
  r.s = &s, r.w = w, r.h = h, r.diag_k = diag_k, r.offdiag_k = offdiag_k, r.rhs = rhs, r.p_out = p_out;
  sharer->share(static_cast<size_t>(s.n), kScaleRows, [](void* c, size_t begin, size_t end) {
    ScaleRange& q = *static_cast<ScaleRange*>(c);
    if (!invert_diagonal(q.w, q.diag_k, static_cast<int>(begin), static_cast<int>(end)))
      q.failed.store(true, std::memory_order_relaxed);
  }, &r);
  if (r.failed.load(std::memory_order_relaxed)) return false;
  sharer->share(static_cast<size_t>(s.n), kScaleRows, [](void* c, size_t begin, size_t end) {
    const ScaleRange& q = *static_cast<const ScaleRange*>(c);
    scale_rows(*q.s, q.w, q.h, q.diag_k, q.offdiag_k, q.rhs, q.p_out, static_cast<int>(begin), static_cast<int>(end));
  }, &r);
  return true;
}

void scale_inverted(const BlockStructure& s, const W_Element* w, float h, const float* dinv, float* offdiag_k,
                    float* rhs, float* p_out) {
  scale_rows(s, w, h, dinv, offdiag_k, rhs, p_out, 0, s.n);
}

void scale_rhs(int n, const float* p, const float* g, float* out) {
  for (int i = 0; i < n; ++i) block_mul(p + kBlockFloats * i, g + kVecFloats * i, out + kVecFloats * i);
}

BlockRowMatrix matrix_of(const BlockStructure& s, const float* blocks) {
  BlockRowMatrix A;
  A.n = s.n;
  A.row_start = s.row_start;
  A.col = s.col;
  A.blocks = blocks;
  A.unit_diagonal = true;
  return A;
}

}  // namespace cellphys::spu
