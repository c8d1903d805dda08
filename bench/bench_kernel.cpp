// One implicit step of the reference island (65 bodies, 400 contacts, 199 blocks),
// whole and by phase, and this core's FMA peak for the efficiency ratio.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <atomic>
#include <cstring>
#include <random>
#include <thread>
#include <vector>

#include "runtime/base/simd.h"
#include "runtime/spu/assembly.h"
#include "runtime/spu/integrators.h"
#include "runtime/spu/kernel.h"
#include "runtime/spu/rigid_motion.h"
#include "testing/reference_island.h"

#if !defined(CELLPHYS_SIMD_SCALAR) && (defined(__AVX2__) || defined(__AVX512F__))
#include <immintrin.h>
#endif

namespace {

using namespace cellphys;
using namespace cellphys::spu;

std::vector<unsigned char> reference_image(Integrator integ, Solver solver) {
  IslandBuilder ib;
  ib.set_integrator(integ);
  ib.set_solver(static_cast<uint32_t>(solver));
  testing::build_reference_island(ib);
  return ib.finish();
}

// The kernel end to end: DMA in, validate, integrate, DMA out.
void BM_ReferenceIslandStep(benchmark::State& state) {
  const auto integ = static_cast<Integrator>(state.range(0));
  const auto solver = static_cast<Solver>(state.range(1));
  const auto img = reference_image(integ, solver);
  std::vector<unsigned char> result(result_bytes(65));
  ComputeWorker w;
  IslandReport r;
  for (auto _ : state) {
    r = w.step(img.data(), img.size(), result.data(), result.size());
    benchmark::DoNotOptimize(result.data());
  }
  state.counters["solver_iterations"] = r.solver_iterations;
  state.counters["local_store_bytes"] = static_cast<double>(r.footprint.total);
  state.SetLabel(std::string(integrator_name(integ)) + (r.status == IslandStatus::ok ? "" : " FAILED"));
}
BENCHMARK(BM_ReferenceIslandStep)
    ->Args({int(Integrator::implicit_split), int(Solver::cgs)})
    ->Args({int(Integrator::implicit_split), int(Solver::bicgstab)})
    ->Args({int(Integrator::implicit_euler), int(Solver::cgs)})
    ->Unit(benchmark::kMicrosecond);

// The phases of one implicit step, on a workspace set up once.
struct Phases {
  std::vector<unsigned char> img = reference_image(Integrator::implicit_split, Solver::cgs);
  LocalStore ls{1 << 20};
  Workspace ws;
  StepContext c;
  Phases() {
    IslandView v = view_island(img.data());
    allocate_workspace(ls, counts_of(v), ws);
    c.island = v;
    c.ws = &ws;
    prepare(c);
  }
  void derivatives(float h) {
    std::memset(ws.forces, 0, sizeof(float) * 8 * ws.n);
    std::memset(ws.diag, 0, sizeof(float) * kBlockFloats * ws.n);
    std::memset(ws.blocks, 0, sizeof(float) * kBlockFloats * ws.structure.nnz);
    for (int i = 0; i < ws.n; ++i) {
      const auto& b = c.island.bodies[i];
      float* u = ws.u0 + 8 * i;
      std::memcpy(u, b.velocity, 12);
      std::memcpy(u + 4, b.angular_velocity, 12);
    }
    ForceTargets t;
    t.forces = ws.forces;
    t.diag_k = ws.diag;
    t.offdiag_k = ws.blocks;
    t.structure = &ws.structure;
    t.h = h;
    t.ref = ws.ref;
    evaluate_forces(c.island, t, ws.force_scratch);
  }
};

void BM_Phase_Derivatives(benchmark::State& state) {
  Phases p;
  for (auto _ : state) p.derivatives(1.0f / 60);
}
BENCHMARK(BM_Phase_Derivatives)->Unit(benchmark::kMicrosecond);

void BM_Phase_Assembly(benchmark::State& state) {
  Phases p;
  std::vector<float> diag(p.ws.n * kBlockFloats), blocks(p.ws.structure.nnz * kBlockFloats), f(p.ws.n * 8);
  p.derivatives(1.0f / 60);
  for (int i = 0; i < p.ws.n; ++i) compute_w(p.c.island.bodies[i], p.ws.w[i]);
  std::memcpy(diag.data(), p.ws.diag, diag.size() * 4);
  std::memcpy(blocks.data(), p.ws.blocks, blocks.size() * 4);
  std::memcpy(f.data(), p.ws.forces, f.size() * 4);
  for (auto _ : state) {
    state.PauseTiming();
    std::memcpy(p.ws.diag, diag.data(), diag.size() * 4);
    std::memcpy(p.ws.blocks, blocks.data(), blocks.size() * 4);
    std::memcpy(p.ws.forces, f.data(), f.size() * 4);
    state.ResumeTiming();
    compute_ws(p.c.island.bodies, p.ws.n, p.ws.w);
    scale_system(p.ws.structure, p.ws.w, 1.0f / 60, p.ws.diag, p.ws.blocks, p.ws.forces, nullptr);
  }
}
BENCHMARK(BM_Phase_Assembly)->Unit(benchmark::kMicrosecond);

// The world inverse inertia of the island's bodies: a body at a time (compute_w), or eight
// in SIMD lanes (compute_ws, what a step does), to the same bits.
void BM_WorldInertia(benchmark::State& state) {
  Phases p;
  const bool lanes = state.range(0) != 0;
  for (auto _ : state) {
    if (lanes) {
      compute_ws(p.c.island.bodies, p.ws.n, p.ws.w);
    } else {
      for (int i = 0; i < p.ws.n; ++i) compute_w(p.c.island.bodies[i], p.ws.w[i]);
    }
    benchmark::DoNotOptimize(p.ws.w);
  }
  state.counters["bodies"] = p.ws.n;
}
BENCHMARK(BM_WorldInertia)->ArgName("lanes")->Arg(0)->Arg(1);

void BM_Phase_Solve(benchmark::State& state) {
  Phases p;
  p.derivatives(1.0f / 60);
  for (int i = 0; i < p.ws.n; ++i) compute_w(p.c.island.bodies[i], p.ws.w[i]);
  scale_system(p.ws.structure, p.ws.w, 1.0f / 60, p.ws.diag, p.ws.blocks, p.ws.forces, nullptr);
  const BlockRowMatrix A = matrix_of(p.ws.structure, p.ws.blocks);
  SolveSettings s;
  SolveResult r;
  for (auto _ : state) {
    std::memset(p.ws.x, 0, sizeof(float) * 8 * p.ws.n);
    r = solve(static_cast<Solver>(state.range(0)), A, p.ws.forces, p.ws.x, p.ws.solver_work, s);
  }
  state.counters["iterations"] = r.iterations;
  state.SetLabel(solver_name(static_cast<Solver>(state.range(0))));
}
BENCHMARK(BM_Phase_Solve)->DenseRange(0, kNumSolvers - 1)->Unit(benchmark::kMicrosecond);

// Single-core FP32 FMA peak: independent accumulator chains, enough to cover the latency.
void BM_PeakFma(benchmark::State& state) {
  constexpr int kChains = 12;
  const long n = 1 << 14;
  double flops_per_iter = 0;
#if !defined(CELLPHYS_SIMD_SCALAR) && defined(__AVX512F__)
  __m512 acc[kChains];
  for (int i = 0; i < kChains; ++i) acc[i] = _mm512_set1_ps(0.0f);
  const __m512 a = _mm512_set1_ps(0.999f), b = _mm512_set1_ps(0.001f);
  for (auto _ : state) {
    for (long k = 0; k < n; ++k)
      for (int i = 0; i < kChains; ++i) acc[i] = _mm512_fmadd_ps(acc[i], a, b);
    benchmark::DoNotOptimize(acc);
  }
  flops_per_iter = 2.0 * 16 * kChains * n;
#elif !defined(CELLPHYS_SIMD_SCALAR) && defined(__AVX2__)
  __m256 acc[kChains];
  for (int i = 0; i < kChains; ++i) acc[i] = _mm256_set1_ps(0.0f);
  const __m256 a = _mm256_set1_ps(0.999f), b = _mm256_set1_ps(0.001f);
  for (auto _ : state) {
    for (long k = 0; k < n; ++k)
      for (int i = 0; i < kChains; ++i) acc[i] = _mm256_fmadd_ps(acc[i], a, b);
    benchmark::DoNotOptimize(acc);
  }
  flops_per_iter = 2.0 * 8 * kChains * n;
#else
  float acc[kChains] = {};
  for (auto _ : state) {
    for (long k = 0; k < n; ++k)
      for (int i = 0; i < kChains; ++i) acc[i] = acc[i] * 0.999f + 0.001f;
    benchmark::DoNotOptimize(acc);
  }
  flops_per_iter = 2.0 * kChains * n;
#endif
  state.counters["GFLOP/s"] = benchmark::Counter(flops_per_iter * static_cast<double>(state.iterations()),
                                                 benchmark::Counter::kIsRate, benchmark::Counter::kIs1000);
  state.SetLabel(cellphys::simd::kPathName);
}
BENCHMARK(BM_PeakFma);

// What a cache line last written by another thread costs to read, against one this thread
// wrote (arg 1 and 0): a random walk over 1,024 lines (64 KiB), each read waiting on the last.
// The stages of a step hand bodies and contacts from thread to thread; where this is many times
// the local figure, spreading a small world's step over two workers costs more than it gains
// (docs/bench.md, "Worker scaling").
void BM_LineFromOtherThread(benchmark::State& state) {
  struct alignas(64) Line {
    Line* next;
    long payload[7];
  };
  constexpr size_t kLines = 1024;
  std::vector<Line> lines(kLines);
  std::vector<size_t> order(kLines);
  for (size_t i = 0; i < kLines; ++i) order[i] = i;
  std::shuffle(order.begin(), order.end(), std::mt19937(1));
  for (size_t i = 0; i < kLines; ++i) lines[order[i]].next = &lines[order[(i + 1) % kLines]];
  const bool other = state.range(0) != 0;
  std::atomic<int> turn{0};  // 1: the writer's turn, 2: the reader's; -1: stop
  auto write_all = [&] {
    for (Line& l : lines) ++l.payload[0];
  };
  std::thread writer([&] {
    for (;;) {
      int t;
      while ((t = turn.load(std::memory_order_acquire)) == 0 || t == 2) {
      }
      if (t < 0) return;
      write_all();
      turn.store(2, std::memory_order_release);
    }
  });
  for (auto _ : state) {
    state.PauseTiming();
    if (other) {
      turn.store(1, std::memory_order_release);
      while (turn.load(std::memory_order_acquire) != 2) {
      }
      turn.store(0, std::memory_order_relaxed);
    } else {
      write_all();
    }
    state.ResumeTiming();
    const Line* p = &lines[order[0]];
    for (size_t i = 0; i < kLines; ++i) p = p->next;
    benchmark::DoNotOptimize(p);
  }
  turn.store(-1, std::memory_order_release);
  writer.join();
  state.counters["ns_per_line"] =
      benchmark::Counter(double(kLines) * double(state.iterations()), benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
  state.SetLabel(other ? "written by another thread" : "written by this thread");
}
BENCHMARK(BM_LineFromOtherThread)->ArgName("other")->Arg(0)->Arg(1)->UseRealTime();

}  // namespace
