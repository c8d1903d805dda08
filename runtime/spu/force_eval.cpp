#include "runtime/spu/force_eval.h"

#include <cstring>

#include "cellphys/gen/block_ops.h"
#include "runtime/base/simd.h"

namespace cellphys::spu {

using namespace cellphys::gen;

namespace {

constexpr int kLanes = 8;
using Batch = simd::Batch<kLanes>;

struct MaxSizes {
  int inputs = 0, outputs = 0;
};

// What a pass over the kernels computes: F only; the implicit form (g and K, the products
// done in SIMD inside the kernel); or F and every Jacobian block (for J v products).
enum class Mode { forces, implicit, full };

Mode mode_of(const ForceTargets& t) {
  if (t.jv_out) return Mode::full;
  if (t.diag_k) return Mode::implicit;
  return Mode::forces;
}

static_assert(kNumForceTypes <= 32, "a force type is a bit of IslandCounts::force_types");

MaxSizes max_sizes(uint32_t types) {
  MaxSizes m;
  visit_kernels([&](auto k) {
    using K = decltype(k);
    if (!(types & (1u << static_cast<uint32_t>(K::kType)))) return;
    if (K::kInputs > m.inputs) m.inputs = K::kInputs;
    if (K::kOutputs > m.outputs) m.outputs = K::kOutputs;
  });
  return m;
}

// One lane of a batch's outputs (out[k * kLanes]) into the targets.
template <class K>
void scatter(const ForceTargets& t, const int (&body)[2], const float* out, Mode mode) {
  for (int k = 0; k < K::kBodies; ++k) {
    float* f = t.forces + kVecFloats * body[k];
    for (int r = 0; r < 6; ++r) f[padded(r)] += out[(6 * k + r) * kLanes];
  }
  if (mode == Mode::implicit) {
    if constexpr (K::kNumImplicitBlocks > 0) {
      for (int s = 0; s < K::kNumImplicitBlocks; ++s) {
        const int i = body[K::kImplicitBlocks[s].row_body], j = body[K::kImplicitBlocks[s].col_body];
        float* target = i == j ? t.diag_k + kBlockFloats * i : t.offdiag_k + kBlockFloats * t.structure->find(i, j);
        const float* B = out + (6 * K::kBodies + 36 * s) * kLanes;
        for (int c = 0; c < 6; ++c)
          for (int r = 0; r < 6; ++r) target[8 * c + padded(r)] += B[(6 * c + r) * kLanes];
      }
    }
  } else if (mode == Mode::full) {
    if constexpr (K::kNumBlocks > 0) {
      for (int s = 0; s < K::kNumBlocks; ++s) {
        const BlockSlot slot = K::kBlocks[s];
        if (slot.kind != BlockKind::dF_ddelta) continue;
        const int i = body[slot.row_body], j = body[slot.col_body];
        const float* B = out + (6 * K::kBodies + 36 * s) * kLanes;
        const float* x = t.jv_in + kVecFloats * j;
        float* y = t.jv_out + kVecFloats * i;
        for (int c = 0; c < 6; ++c)
          for (int r = 0; r < 6; ++r) y[padded(r)] += B[(6 * c + r) * kLanes] * x[padded(c)];
      }
    }
  }
}

// A batch's 6 consecutive output rows (a 6-vector, or one column of a 6x6 block) as one
// padded 8-float column per lane (x y z 0 x y z 0): one transpose instead of strided loads.
void columns_of(const float* out_soa, int first_row, float* tile) {
  alignas(32) static const float zero[kLanes] = {};
  const float* rows[8];
  for (int p = 0; p < 8; ++p)
    rows[p] = (p == 3 || p == 7) ? zero : out_soa + (first_row + (p < 3 ? p : p - 1)) * kLanes;
  simd::transpose8(rows, tile);
}

void add_column(float* target, const float* column) {
  simd::store(target, simd::add(simd::load<simd::vf8>(target), simd::load<simd::vf8>(column)));
}

// The forces and implicit blocks of a whole batch, lane by lane, through transposed tiles.
template <class K>
void scatter_batch(const ForceTargets& t, const int (*body)[2], int lanes, const float* out_soa, Mode mode) {
  alignas(32) float tile[8 * kLanes];
  for (int k = 0; k < K::kBodies; ++k) {
    columns_of(out_soa, 6 * k, tile);
    for (int l = 0; l < lanes; ++l) add_column(t.forces + kVecFloats * body[l][k], tile + 8 * l);
  }
  if (mode != Mode::implicit) return;
  if constexpr (K::kNumImplicitBlocks > 0) {
    for (int s = 0; s < K::kNumImplicitBlocks; ++s) {
      float* target[kLanes];
      for (int l = 0; l < lanes; ++l) {
        const int i = body[l][K::kImplicitBlocks[s].row_body], j = body[l][K::kImplicitBlocks[s].col_body];
        target[l] = i == j ? t.diag_k + kBlockFloats * i : t.offdiag_k + kBlockFloats * t.structure->find(i, j);
      }
      for (int c = 0; c < 6; ++c) {
        columns_of(out_soa, 6 * K::kBodies + 36 * s + 6 * c, tile);
        for (int l = 0; l < lanes; ++l) add_column(target[l] + 8 * c, tile + 8 * l);
      }
    }
  }
}

template <class K>
constexpr int outputs_of(Mode m) {
  return m == Mode::forces ? 6 * K::kBodies : m == Mode::implicit ? K::kImplicitOutputs : K::kOutputs;
}

template <class K>
void run_kernel(const IslandView& v, const ForceTargets& t, const typename K::Instance* inst, int count,
                bool global, float* scratch) {
  const Mode mode = mode_of(t);
  float* in_soa = scratch;                            // kInputs x kLanes
  float* out_soa = scratch + kLanes * K::kInputs;     // kOutputs x kLanes
  alignas(32) Batch in[K::kInputs > 0 ? K::kInputs : 1];
  alignas(32) Batch out[K::kOutputs];
  for (int base = 0; base < count; base += kLanes) {
    const int lanes = count - base < kLanes ? count - base : kLanes;
    int bodies[kLanes][2];
    for (int l = 0; l < kLanes; ++l) {
      // idle lanes repeat the last instance: always finite, results discarded
      const int idx = base + (l < lanes ? l : lanes - 1);
      typename K::Instance synthetic{};
      const typename K::Instance* f = &synthetic;
      if (global)
        synthetic.body_a = idx;
      else
        f = inst + idx;
      bodies[l][0] = f->body_a;
      if constexpr (K::kBodies == 2) bodies[l][1] = f->body_b;
      else bodies[l][1] = f->body_a;
      K::gather(v.bodies, *f, *v.params, in_soa + l, t.ref, kLanes);
    }
    for (int k = 0; k < K::kInputs; ++k) in[k] = Batch::load(in_soa + k * kLanes);
    if (mode == Mode::implicit)
      K::template eval_implicit<Batch>(in, Batch(t.h), out);
    else if (mode == Mode::full)
      K::template eval<Batch>(in, Batch(t.h), out);
    else
      K::template eval_f<Batch>(in, Batch(t.h), out);
    const int n_out = outputs_of<K>(mode);
    for (int k = 0; k < n_out; ++k) out[k].store(out_soa + k * kLanes);
    if (mode == Mode::full) {
      for (int l = 0; l < lanes; ++l) {
        const int b2[2] = {bodies[l][0], bodies[l][1]};
        scatter<K>(t, b2, out_soa + l, mode);
      }
    } else {
      scatter_batch<K>(t, bodies, lanes, out_soa, mode);
    }
  }
}

}  // namespace

int BlockStructure::find(int row, int column) const {
  for (int k = row_start[row]; k < row_start[row + 1]; ++k)
    if (col[k] == column) return k;
  return -1;
}

size_t force_scratch_bytes(uint32_t types) {
  const MaxSizes m = max_sizes(types);
  return sizeof(float) * kLanes * static_cast<size_t>(m.inputs + m.outputs);
}

void evaluate_forces(const IslandView& v, const ForceTargets& t, float* scratch) {
  for (int s = 0; s < v.num_sections(); ++s) {
    const Island_Section& sec = v.sections[s];
    if (t.skip_types & (1u << sec.force_type)) continue;
    visit_kernels([&](auto k) {
      using K = decltype(k);
      if (static_cast<uint32_t>(K::kType) != sec.force_type) return;
      const auto* inst = v.instances<typename K::Instance>(sec);
      const int pairs = static_cast<int>(sec.count - sec.world_count);
      const bool global = kForceTable[sec.force_type].kind == ForceKind::global;
      if constexpr (K::kVariant == KernelVariant::world)
        run_kernel<K>(v, t, inst + pairs, static_cast<int>(sec.world_count), false, scratch);
      else if (global)
        run_kernel<K>(v, t, nullptr, v.num_bodies(), true, scratch);
      else
        run_kernel<K>(v, t, inst, pairs, false, scratch);
    });
  }
}

}  // namespace cellphys::spu
