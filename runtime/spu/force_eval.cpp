#include "runtime/spu/force_eval.h"

#include <cassert>
#include <cstdint>
#include <cstring>

#include "cellphys/gen/block_ops.h"
#include "runtime/base/simd.h"

namespace cellphys::spu {

using namespace cellphys::gen;

namespace {

constexpr int kLanes = 8;
using Batch = simd::Batch<kLanes>;
static_assert(sizeof(Batch) == kLanes * sizeof(float) && alignof(Batch) <= 32,
              "a row of kLanes floats in the scratch is one Batch");

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
// padded 8-float column per lane (x y z 0 x y z 0), added into target(l) lane by lane in
// order: one transpose, in registers, instead of strided loads. Consecutive lanes with one
// target (a pair's manifold points) keep the running sum in a register and store it once: the
// same adds in the same order, so the same bits, without each add waiting for the last one's
// store.
template <class Target>
void add_rows(const float* out_soa, int first_row, int lanes, Target target) {
  alignas(32) static const float zero[kLanes] = {};
  const float* rows[8];
  for (int p = 0; p < 8; ++p)
    rows[p] = (p == 3 || p == 7) ? zero : out_soa + (first_row + (p < 3 ? p : p - 1)) * kLanes;
  simd::vf8 column[8];
  simd::transpose8(rows, column);
  float* t = nullptr;
  simd::vf8 sum;
  for (int l = 0; l < kLanes && l < lanes; ++l) {
    float* const tl = target(l);
    if (tl != t) {
      if (t) simd::store(t, sum);
      t = tl;
      sum = simd::load<simd::vf8>(t);
    }
    sum = simd::add(sum, column[l]);
  }
  if (t) simd::store(t, sum);
}

// The forces and implicit blocks of a whole batch, through transposed tiles, each lane into
// its own island's targets: every lane's body a, then every lane's body b, then each block.
// A target is added to in instance order when the kernel has one body; a pair kernel's body
// that is body b of one lane and body a of a later one receives the later lane's first, so its
// sums depend on where the batches split an island's pairs (push_section splits them as alone).
template <class K>
void scatter_batch(const ForceTargets* const* t, const int (*body)[2], int lanes, const float* out_soa, Mode mode) {
  for (int k = 0; k < K::kBodies; ++k)
    add_rows(out_soa, 6 * k, lanes, [&](int l) { return t[l]->forces + kVecFloats * body[l][k]; });
  if (mode != Mode::implicit) return;
  if constexpr (K::kNumImplicitBlocks > 0) {
    for (int s = 0; s < K::kNumImplicitBlocks; ++s) {
      float* target[kLanes];
      for (int l = 0; l < lanes; ++l) {
        const int i = body[l][K::kImplicitBlocks[s].row_body], j = body[l][K::kImplicitBlocks[s].col_body];
        if (l > 0 && t[l] == t[l - 1] && body[l][0] == body[l - 1][0] && body[l][1] == body[l - 1][1]) {
          target[l] = target[l - 1];  // the same pair: the same block
          continue;
        }
        target[l] = i == j ? t[l]->diag_k + kBlockFloats * i : t[l]->offdiag_k + kBlockFloats * t[l]->structure->find(i, j);
      }
      for (int c = 0; c < 6; ++c)
        add_rows(out_soa, 6 * K::kBodies + 36 * s + 6 * c, lanes, [&](int l) { return target[l] + 8 * c; });
    }
  }
}

// Fills kernel K's SIMD lanes with instances, from one island or several, and runs a batch
// each time the lanes are full. A lane's result goes to its own island's targets. One-body
// kernels (world contacts, gravity) share batches across islands; a pair kernel's island
// shares one only when its pairs all fit the lanes left, and starts at lane 0 otherwise
// (push_section), so every island's forces come out as they do alone.
template <class K>
class LaneBatch {
 public:
  LaneBatch(Mode mode, float h, float* scratch) : mode_(mode), h_(h), scratch_(scratch) {
    assert(reinterpret_cast<uintptr_t>(scratch) % 32 == 0);
  }
  // inst null: a global force on body `body`
  void push(const ForceJob& j, const typename K::Instance* inst, int body) {
    lanes_[n_++] = {&j, inst, body};
    if (n_ == kLanes) flush();
  }
  int free_lanes() const { return kLanes - n_; }
  void flush() {
    if (n_ == 0) return;
    // The kernel reads and writes the scratch in place: kInputs, then kOutputs, rows of kLanes
    // floats are a Batch each (no copy in and out, and nothing zeroed per batch; every kernel
    // entry point writes each of its outputs).
    float* in_soa = scratch_;                         // kInputs x kLanes
    float* out_soa = scratch_ + kLanes * K::kInputs;  // kOutputs x kLanes
    const Batch* in = reinterpret_cast<const Batch*>(in_soa);
    Batch* out = reinterpret_cast<Batch*>(out_soa);
    int bodies[kLanes][2];
    const ForceTargets* targets[kLanes];
    typename K::Instance synthetic{};  // a global force's instance: only its body
    for (int l = 0; l < kLanes; ++l) {
      // idle lanes repeat the last instance: always finite, results discarded
      const Lane& lane = lanes_[l < n_ ? l : n_ - 1];
      const typename K::Instance* f = lane.inst;
      if (!f) {
        synthetic.body_a = lane.body;
        f = &synthetic;
      }
      bodies[l][0] = f->body_a;
      if constexpr (K::kBodies == 2) bodies[l][1] = f->body_b;
      else bodies[l][1] = f->body_a;
      targets[l] = lane.job->t;
      K::gather(lane.job->v->bodies, *f, *lane.job->v->params, in_soa + l, lane.job->t->ref, kLanes);
    }
    if (mode_ == Mode::implicit)
      K::template eval_implicit<Batch>(in, Batch(h_), out);
    else if (mode_ == Mode::full)
      K::template eval<Batch>(in, Batch(h_), out);
    else
      K::template eval_f<Batch>(in, Batch(h_), out);
    if (mode_ == Mode::full) {
      for (int l = 0; l < n_; ++l) scatter<K>(*targets[l], bodies[l], out_soa + l, mode_);
    } else {
      scatter_batch<K>(targets, bodies, n_, out_soa, mode_);
    }
    n_ = 0;
  }

 private:
  struct Lane {
    const ForceJob* job;
    const typename K::Instance* inst;
    int body;
  };
  Mode mode_;
  float h_;
  float* scratch_;
  Lane lanes_[kLanes];
  int n_ = 0;
};

// Pushes island j's instances of section sec for kernel K (its variant's share of them).
template <class K>
void push_section(LaneBatch<K>& batch, const ForceJob& j, const Island_Section& sec) {
  const IslandView& v = *j.v;
  const auto* inst = v.instances<typename K::Instance>(sec);
  const int pairs = static_cast<int>(sec.count - sec.world_count);
  if constexpr (K::kVariant == KernelVariant::world) {
    for (uint32_t k = 0; k < sec.world_count; ++k) batch.push(j, inst + pairs + k, 0);
  } else if (kForceTable[sec.force_type].kind == ForceKind::global) {
    for (int b = 0; b < v.num_bodies(); ++b) batch.push(j, nullptr, b);
  } else {
    // The island's pairs batched as they are alone (scatter_batch): from lane 0 of a batch,
    // or after other islands' pairs when all of its own fit the lanes left. Its targets then
    // receive the same adds in the same order (the other lanes add to other islands' only),
    // and two-box islands share one batch instead of leaving half of each idle.
    if (pairs > batch.free_lanes()) batch.flush();
    for (int k = 0; k < pairs; ++k) batch.push(j, inst + k, 0);
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
  const ForceJob job{&v, &t};
  const Mode mode = mode_of(t);
  for (int s = 0; s < v.num_sections(); ++s) {
    const Island_Section& sec = v.sections[s];
    if (t.skip_types & (1u << sec.force_type)) continue;
    visit_kernels([&](auto k) {
      using K = decltype(k);
      if (static_cast<uint32_t>(K::kType) != sec.force_type) return;
      LaneBatch<K> batch(mode, t.h, scratch);
      push_section(batch, job, sec);
      batch.flush();
    });
  }
}

void evaluate_forces_together(const ForceJob* jobs, int count, float* scratch) {
  if (count <= 0) return;
  const ForceTargets& t0 = *jobs[0].t;
  const Mode mode = mode_of(t0);
  for (uint32_t type = 0; type < static_cast<uint32_t>(kNumForceTypes); ++type) {
    visit_kernels([&](auto k) {
      using K = decltype(k);
      if (static_cast<uint32_t>(K::kType) != type) return;
      LaneBatch<K> batch(mode, t0.h, scratch);
      for (int j = 0; j < count; ++j) {
        if (jobs[j].t->skip_types & (1u << type)) continue;
        const IslandView& v = *jobs[j].v;
        for (int s = 0; s < v.num_sections(); ++s)
          if (v.sections[s].force_type == type) push_section(batch, jobs[j], v.sections[s]);
      }
      batch.flush();
    });
  }
}

}  // namespace cellphys::spu
