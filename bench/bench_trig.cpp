// The cost of the determinism policy's own sine and cosine (runtime/base/trig.h, used by the
// rotation's exponential map) against libm's, side by side: the half-angles a step turns a body
// by (0..0.5 rad, arg 0) and wide arguments (0..100 rad, arg 1). docs/determinism.md quotes it.
#include <benchmark/benchmark.h>

#include <cmath>
#include <random>
#include <vector>

#include "runtime/base/trig.h"

namespace {

std::vector<double> angles(bool wide) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> U(0.0, wide ? 100.0 : 0.5);
  std::vector<double> x(4096);
  for (double& a : x) a = U(rng);
  return x;
}

void BM_OwnSinCos(benchmark::State& state) {
  const std::vector<double> x = angles(state.range(0) == 1);
  double sum = 0;
  for (auto _ : state)
    for (double a : x) {
      double s, c;
      cellphys::sin_cos(a, &s, &c);
      sum += s + c;
    }
  benchmark::DoNotOptimize(sum);
  state.SetItemsProcessed(int64_t(state.iterations()) * int64_t(x.size()));
}
BENCHMARK(BM_OwnSinCos)->ArgName("wide")->Arg(0)->Arg(1);

void BM_LibmSinCos(benchmark::State& state) {
  const std::vector<double> x = angles(state.range(0) == 1);
  double sum = 0;
  for (auto _ : state)
    for (double a : x) sum += std::sin(a) + std::cos(a);
  benchmark::DoNotOptimize(sum);
  state.SetItemsProcessed(int64_t(state.iterations()) * int64_t(x.size()));
}
BENCHMARK(BM_LibmSinCos)->ArgName("wide")->Arg(0)->Arg(1);

}  // namespace
