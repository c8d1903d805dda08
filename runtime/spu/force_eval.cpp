#include "runtime/spu/force_eval.h"

#include <cstring>

#include "cellphys/gen/block_ops.h"
#include "runtime/spu/simd.h"

namespace cellphys::spu {

using namespace cellphys::gen;

namespace {

constexpr int kLanes = 8;
using Batch = simd::Batch<kLanes>;

struct MaxSizes {
  int inputs = 0, outputs = 0;
};

MaxSizes max_sizes() {
  MaxSizes m;
  visit_kernels([&](auto k) {
    using K = decltype(k);
    if (K::kInputs > m.inputs) m.inputs = K::kInputs;
    if (K::kOutputs > m.outputs) m.outputs = K::kOutputs;
  });
  return m;
}

// One instance's bodies and its slice of a batch's outputs.
template <class K>
void scatter(const ForceTargets& t, const int (&body)[2], const float* out, bool jacobians) {
  for (int k = 0; k < K::kBodies; ++k) {
    float* f = t.forces + kVecFloats * body[k];
    for (int r = 0; r < 6; ++r) f[padded(r)] += out[6 * k + r];
  }
  if (!jacobians) return;
  if constexpr (K::kNumBlocks > 0) {
    const float h = t.h;
    for (int s = 0; s < K::kNumBlocks; ++s) {
      const BlockSlot slot = K::kBlocks[s];
      const float* B = out + 6 * K::kBodies + 36 * s;
      const int i = body[slot.row_body], j = body[slot.col_body];
      const bool dd = slot.kind == BlockKind::dF_ddelta;
      if (t.diag_k) {
        float* target = i == j ? t.diag_k + kBlockFloats * i : t.offdiag_k + kBlockFloats * t.structure->find(i, j);
        block_add_dense(dd ? h * h : h, B, target);
      }
      if (dd && t.u0) dense_mul_add(h, B, t.u0 + kVecFloats * j, t.forces + kVecFloats * i);
      if (dd && t.jv_out) dense_mul_add(1.0f, B, t.jv_in + kVecFloats * j, t.jv_out + kVecFloats * i);
    }
  }
}

template <class K>
void run_kernel(const IslandView& v, const ForceTargets& t, const typename K::Instance* inst, int count,
                bool global, float* scratch) {
  const bool jacobians = t.diag_k || t.u0 || t.jv_out;
  float* in_soa = scratch;                            // kInputs x kLanes
  float* out_soa = scratch + kLanes * K::kInputs;     // kOutputs x kLanes
  alignas(32) Batch in[K::kInputs > 0 ? K::kInputs : 1];
  alignas(32) Batch out[K::kOutputs];
  for (int base = 0; base < count; base += kLanes) {
    const int lanes = count - base < kLanes ? count - base : kLanes;
    int bodies[kLanes][2];
    float lane_in[K::kInputs > 0 ? K::kInputs : 1];
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
      K::gather(v.bodies, *f, *v.params, lane_in);
      for (int k = 0; k < K::kInputs; ++k) in_soa[k * kLanes + l] = lane_in[k];
    }
    for (int k = 0; k < K::kInputs; ++k) in[k] = Batch::load(in_soa + k * kLanes);
    if (jacobians)
      K::template eval<Batch>(in, out);
    else
      K::template eval_f<Batch>(in, out);
    const int n_out = jacobians ? K::kOutputs : 6 * K::kBodies;
    for (int k = 0; k < n_out; ++k) out[k].store(out_soa + k * kLanes);
    float lane_out[K::kOutputs];
    for (int l = 0; l < lanes; ++l) {
      for (int k = 0; k < n_out; ++k) lane_out[k] = out_soa[k * kLanes + l];
      const int b2[2] = {bodies[l][0], bodies[l][1]};
      scatter<K>(t, b2, lane_out, jacobians);
    }
  }
}

}  // namespace

int BlockStructure::find(int row, int column) const {
  for (int k = row_start[row]; k < row_start[row + 1]; ++k)
    if (col[k] == column) return k;
  return -1;
}

size_t force_scratch_bytes() {
  static const MaxSizes m = max_sizes();
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
