// Block multiply-accumulate throughput (y += B x on padded 8x6 blocks), in GFLOP/s.
// 6 columns x 6 logical rows x 2 flops = 72 useful flops per block (padding not counted).
#include <benchmark/benchmark.h>

#include <random>
#include <vector>

#include "cellphys/gen/block_ops.h"

namespace {

struct alignas(32) Block {
  float m[48];
};
struct alignas(32) Vec8 {
  float v[8];
};

void BM_BlockMulAdd(benchmark::State& state) {
  // Many independent blocks, as in a block row sweep; sized to stay in L1/L2.
  const int n = static_cast<int>(state.range(0));
  std::mt19937 rng(1);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  std::vector<Block> blocks(n);
  std::vector<Vec8> x(n), y(n);
  for (int i = 0; i < n; ++i) {
    for (int c = 0; c < 6; ++c)
      for (int r = 0; r < 6; ++r) blocks[i].m[8 * c + cellphys::gen::padded(r)] = u(rng);
    for (int r = 0; r < 6; ++r) x[i].v[cellphys::gen::padded(r)] = u(rng);
    y[i] = Vec8{};
  }
  for (auto _ : state) {
    for (int i = 0; i < n; ++i) cellphys::gen::block_mul_add(blocks[i].m, x[i].v, y[i].v);
    benchmark::ClobberMemory();
  }
  state.counters["GFLOP/s"] =
      benchmark::Counter(72.0 * n * static_cast<double>(state.iterations()), benchmark::Counter::kIsRate,
                         benchmark::Counter::kIs1000);
  state.SetLabel(cellphys::simd::kPathName);
}
BENCHMARK(BM_BlockMulAdd)->Arg(64)->Arg(256)->Arg(2048);

}  // namespace
