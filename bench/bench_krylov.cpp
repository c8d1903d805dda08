// Island solver costs on a matrix shaped like the reference island: 65 bodies,
// 67 touching pairs x 6 contacts (402 contacts), 65 + 134 = 199 non-zero blocks,
// stored block-Jacobi scaled (unit diagonal) as block_sparse.h describes.
//
// Flop count for spmv: 72 useful flops per stored 6x6 block (36 multiplies + 36 adds on
// logical entries; the padding lanes the SIMD code also computes are not counted). The
// unit diagonal is a copy and counts nothing; with a stored diagonal (the reference design's unscaled
// form, Arg 1) each diagonal block counts 72 as well.
#include <benchmark/benchmark.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <random>
#include <string>
#include <vector>

#include "cellphys/gen/block_ops.h"
#include "runtime/spu/block_sparse.h"
#include "runtime/spu/krylov.h"

namespace {

using namespace cellphys::spu;
namespace gen = cellphys::gen;

struct alignas(32) Block {
  float m[kBlockFloats];
};
struct alignas(32) Vec8 {
  float v[kVecFloats];
};
using Mat6 = double[6][6];

void add_to(Block& B, const Mat6& M) {
  for (int c = 0; c < 6; ++c)
    for (int r = 0; r < 6; ++r) B.m[8 * c + gen::padded(r)] += static_cast<float>(M[r][c]);
}

struct Island {
  int n = 65;
  std::vector<int32_t> row_start, col;
  std::vector<Block> blocks;  // scaled off-diagonal blocks D_i^-1 A_ij
  std::vector<Block> diag;    // unscaled diagonal A_ii, for the stored-diagonal variant
  std::vector<Block> raw;     // unscaled off-diagonal A_ij, same order as blocks
  std::vector<Vec8> b;        // scaled right-hand side D^-1 b

  BlockRowMatrix scaled() const {
    return {n, row_start.data(), col.data(), blocks[0].m, true, nullptr};
  }
  BlockRowMatrix unscaled() const {
    return {n, row_start.data(), col.data(), raw[0].m, false, diag[0].m};
  }
};

// A = M + k sum_c g g^T over contact rows g = (n, r x n) per body, plus a small skew part
// (friction/gyroscopic-like): the same construction as the tests' reference island.
Island make_island() {
  Island I;
  const int n = I.n;
  const double k = 30.0, skew = 0.02;
  std::mt19937 rng(65);
  std::uniform_real_distribution<double> u01(0.0, 1.0), u11(-1.0, 1.0);
  std::normal_distribution<double> g;

  std::vector<std::pair<int, int>> pairs;  // random tree plus three extra pairs
  for (int i = 1; i < n; ++i) pairs.push_back({std::uniform_int_distribution<int>(0, i - 1)(rng), i});
  while (pairs.size() < 67) {
    const int i = std::uniform_int_distribution<int>(0, n - 1)(rng);
    const int j = std::uniform_int_distribution<int>(0, n - 1)(rng);
    bool dup = i == j;
    for (auto& p : pairs) dup = dup || (p.first == i && p.second == j) || (p.first == j && p.second == i);
    if (!dup) pairs.push_back({i, j});
  }

  std::vector<Block> D(n, Block{});
  for (int i = 0; i < n; ++i) {
    const double m = 0.5 + 1.5 * u01(rng);
    const double qw = g(rng), qx = g(rng), qy = g(rng), qz = g(rng);
    const double s = 1.0 / std::sqrt(qw * qw + qx * qx + qy * qy + qz * qz);
    const double w = qw * s, x = qx * s, y = qy * s, z = qz * s;
    const double R[3][3] = {{1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)},
                            {2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)},
                            {2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)}};
    const double inertia[3] = {m * (0.1 + u01(rng)), m * (0.1 + u01(rng)), m * (0.1 + u01(rng))};
    Mat6 M = {};
    for (int a = 0; a < 3; ++a) {
      M[a][a] = m;
      for (int c = 0; c < 3; ++c)
        for (int e = 0; e < 3; ++e) M[3 + a][3 + c] += R[a][e] * inertia[e] * R[c][e];
    }
    for (int a = 0; a < 6; ++a)
      for (int c = 0; c < a; ++c) {
        const double t = skew * u11(rng);
        M[a][c] += t;
        M[c][a] -= t;
      }
    add_to(D[i], M);
  }

  struct Off {
    int i, j;
    Block B;
  };
  std::vector<Off> off;
  for (auto [i, j] : pairs) {
    Mat6 Kii = {}, Kjj = {}, Kij = {}, Kji = {};
    for (int c = 0; c < 6; ++c) {
      double nv[3], ri[3], rj[3];
      for (double& e : nv) e = g(rng);
      const double len = std::sqrt(nv[0] * nv[0] + nv[1] * nv[1] + nv[2] * nv[2]);
      for (double& e : nv) e /= len;
      for (double& e : ri) e = 0.5 * u11(rng);
      for (double& e : rj) e = 0.5 * u11(rng);
      auto row = [&](const double* r, double sign, double* out) {  // sign * (n, r x n)
        out[0] = sign * nv[0], out[1] = sign * nv[1], out[2] = sign * nv[2];
        out[3] = sign * (r[1] * nv[2] - r[2] * nv[1]);
        out[4] = sign * (r[2] * nv[0] - r[0] * nv[2]);
        out[5] = sign * (r[0] * nv[1] - r[1] * nv[0]);
      };
      double gi[6], gj[6];
      row(ri, 1.0, gi);
      row(rj, -1.0, gj);
      for (int a = 0; a < 6; ++a)
        for (int e = 0; e < 6; ++e) {
          Kii[a][e] += k * gi[a] * gi[e];
          Kjj[a][e] += k * gj[a] * gj[e];
          Kij[a][e] += k * gi[a] * gj[e];
          Kji[a][e] += k * gj[a] * gi[e];
        }
    }
    for (int a = 0; a < 6; ++a)
      for (int e = 0; e < 6; ++e) {
        const double t = skew * k * u11(rng);  // +E at (i, j), -E^T at (j, i)
        Kij[a][e] += t;
        Kji[e][a] -= t;
      }
    add_to(D[i], Kii);
    add_to(D[j], Kjj);
    off.push_back({i, j, Block{}});
    add_to(off.back().B, Kij);
    off.push_back({j, i, Block{}});
    add_to(off.back().B, Kji);
  }

  std::vector<Block> Dinv(n);
  for (int i = 0; i < n; ++i)
    if (!gen::block_jacobi_inverse(D[i].m, Dinv[i].m)) std::abort();  // SPD + skew: invertible

  I.row_start.assign(n + 1, 0);
  for (int i = 0; i < n; ++i) {
    for (const Off& o : off) {
      if (o.i != i) continue;
      I.col.push_back(o.j);
      I.raw.push_back(o.B);
      I.blocks.emplace_back();
      gen::block_mul_block(Dinv[i].m, o.B.m, I.blocks.back().m);
    }
    I.row_start[i + 1] = static_cast<int32_t>(I.col.size());
  }
  I.diag = D;
  I.b.assign(n, Vec8{});
  for (int i = 0; i < n; ++i) {
    alignas(32) float raw_b[8] = {};
    for (int r = 0; r < 6; ++r) raw_b[gen::padded(r)] = static_cast<float>(u11(rng));
    gen::block_mul(Dinv[i].m, raw_b, I.b[i].v);
  }
  return I;
}

const Island& island() {
  static const Island I = make_island();
  return I;
}

void BM_Spmv(benchmark::State& state) {
  const Island& I = island();
  const bool stored_diag = state.range(0) != 0;
  const BlockRowMatrix A = stored_diag ? I.unscaled() : I.scaled();
  std::vector<Vec8> x = I.b, y(I.n);
  for (auto _ : state) {
    spmv(A, x[0].v, y[0].v);
    benchmark::DoNotOptimize(y.data());
    benchmark::ClobberMemory();
  }
  const double blocks = static_cast<double>(I.blocks.size()) + (stored_diag ? I.n : 0);
  state.counters["blocks"] = blocks;
  state.counters["GFLOP/s"] = benchmark::Counter(72.0 * blocks * static_cast<double>(state.iterations()),
                                                 benchmark::Counter::kIsRate, benchmark::Counter::kIs1000);
  state.SetLabel(std::string(cellphys::simd::kPathName) + (stored_diag ? " stored diagonal" : " unit diagonal"));
}
BENCHMARK(BM_Spmv)->ArgName("stored_diag")->Arg(0)->Arg(1);

// Arg: -log10(rel_tol). abs_tol = 0 so the relative tolerance alone decides.
template <SolveResult (*Solve)(const BlockRowMatrix&, const float*, float*, float*, const SolveSettings&)>
void BM_Krylov(benchmark::State& state) {
  const Island& I = island();
  const BlockRowMatrix A = I.scaled();
  SolveSettings s;
  s.rel_tol = static_cast<float>(std::pow(10.0, -static_cast<double>(state.range(0))));
  s.abs_tol = 0.0f;
  std::vector<Vec8> x(I.n), work(static_cast<size_t>(kCgsWorkVectors > kBicgstabWorkVectors ? kCgsWorkVectors
                                                                                             : kBicgstabWorkVectors) * I.n);
  SolveResult r;
  for (auto _ : state) {
    zero(I.n, x[0].v);
    r = Solve(A, I.b[0].v, x[0].v, work[0].v, s);
    benchmark::DoNotOptimize(x.data());
  }
  // Same input every solve, so the last result is every result.
  state.counters["iterations"] = r.iterations;
  state.counters["code"] = r.code;
  state.counters["residual"] = r.residual;
  if (r.code != kConverged) state.SkipWithError("did not converge");
  state.SetLabel(cellphys::simd::kPathName);
}
void BM_Cgs(benchmark::State& state) { BM_Krylov<cgs>(state); }
void BM_Bicgstab(benchmark::State& state) { BM_Krylov<bicgstab>(state); }
BENCHMARK(BM_Cgs)->ArgName("neg_log10_tol")->Arg(3)->Arg(5)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_Bicgstab)->ArgName("neg_log10_tol")->Arg(3)->Arg(5)->Unit(benchmark::kMicrosecond);

// Assembly of the Eigen matrix, factorization and solve: what direct_lu does per call.
void BM_DirectLu(benchmark::State& state) {
  const Island& I = island();
  const BlockRowMatrix A = I.scaled();
  std::vector<Vec8> x(I.n);
  SolveResult r;
  for (auto _ : state) {
    r = direct_lu(A, I.b[0].v, x[0].v);
    benchmark::DoNotOptimize(x.data());
  }
  state.counters["residual"] = r.residual;
  if (r.code != kConverged) state.SkipWithError("factorization failed");
}
BENCHMARK(BM_DirectLu)->Unit(benchmark::kMicrosecond);

}  // namespace
