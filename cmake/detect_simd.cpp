// Prints the widest SIMD path this machine runs: avx512, avx2 or scalar.
#include <cstdio>
int main() {
  __builtin_cpu_init();
  if (__builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512vl") && __builtin_cpu_supports("avx512dq"))
    std::puts("avx512");
  else if (__builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma"))
    std::puts("avx2");
  else
    std::puts("scalar");
  return 0;
}
