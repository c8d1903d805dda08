// Eight doubles computed side by side, as a scalar type for the templates of vec3.h, quat.h and
// mat3.h: Vec3<DoubleLanes> is eight 3-vectors, one a lane. Each operation is the IEEE one of
// every lane (+ - * / and sqrt round once, nothing is contracted: the build uses
// -ffp-contract=off), so a lane's result has the bits the same expression gives in double.
// Compiled to one AVX-512 register, two AVX2 ones, or four SSE2 ones on the portable path.
#pragma once
#include <cmath>
#include <cstdint>
#include <cstring>

#if defined(__AVX__)
#include <immintrin.h>
#endif

namespace cellphys {

struct DoubleLanes {
  static constexpr int kLanes = 8;
  using Raw = double __attribute__((vector_size(8 * sizeof(double))));
  using RawMask = int64_t __attribute__((vector_size(8 * sizeof(int64_t))));
  Raw v;

  DoubleLanes() : v{} {}
  DoubleLanes(double s) : v{s, s, s, s, s, s, s, s} {}  // implicit: 2 * x broadcasts as double does
  explicit DoubleLanes(Raw r) : v(r) {}
  double operator[](int k) const { return v[k]; }
  void set(int k, double s) { v[k] = s; }

  friend DoubleLanes operator+(DoubleLanes a, DoubleLanes b) { return DoubleLanes(a.v + b.v); }
  friend DoubleLanes operator-(DoubleLanes a, DoubleLanes b) { return DoubleLanes(a.v - b.v); }
  friend DoubleLanes operator*(DoubleLanes a, DoubleLanes b) { return DoubleLanes(a.v * b.v); }
  friend DoubleLanes operator/(DoubleLanes a, DoubleLanes b) { return DoubleLanes(a.v / b.v); }
  friend DoubleLanes operator-(DoubleLanes a) { return DoubleLanes(-a.v); }
  DoubleLanes& operator+=(DoubleLanes b) { return v += b.v, *this; }
  friend DoubleLanes sqrt(DoubleLanes a) {
    // In registers: halves stored apart and read back as one vector waited for the stores to
    // drain (a failed store-to-load forward, the most of the batched rotation kick's time).
#if defined(__AVX512F__)  // one 8-wide root (masked, every lane: GCC 12 warns on the unmasked form)
    const __m512d x = __m512d(a.v);
    return DoubleLanes(Raw(_mm512_mask_sqrt_pd(x, 0xFF, x)));
#elif defined(__AVX__)  // two 4-wide roots
    using Half = double __attribute__((vector_size(4 * sizeof(double))));
    const Half lo = __builtin_shufflevector(a.v, a.v, 0, 1, 2, 3), hi = __builtin_shufflevector(a.v, a.v, 4, 5, 6, 7);
    const Half rl = Half(_mm256_sqrt_pd(__m256d(lo))), rh = Half(_mm256_sqrt_pd(__m256d(hi)));
    return DoubleLanes(Raw(__builtin_shufflevector(rl, rh, 0, 1, 2, 3, 4, 5, 6, 7)));
#else
    DoubleLanes r;
    for (int k = 0; k < kLanes; ++k) r.v[k] = std::sqrt(a.v[k]);
    return r;
#endif
  }
};

/// A lane mask: every bit of a lane set (true) or clear.
struct LaneMask {
  DoubleLanes::RawMask m;
  bool operator[](int k) const { return m[k] != 0; }
  friend LaneMask operator|(LaneMask a, LaneMask b) { return {a.m | b.m}; }
};
inline LaneMask operator<=(DoubleLanes a, DoubleLanes b) { return {a.v <= b.v}; }
inline LaneMask lanes_where(const bool (&b)[DoubleLanes::kLanes]) {
  LaneMask r{};
  for (int k = 0; k < DoubleLanes::kLanes; ++k) r.m[k] = b[k] ? -1 : 0;
  return r;
}
inline bool every(LaneMask a) {
  for (int k = 0; k < DoubleLanes::kLanes; ++k)
    if (!a.m[k]) return false;
  return true;
}
/// m ? a : b, lane by lane.
inline DoubleLanes pick(LaneMask m, DoubleLanes a, DoubleLanes b) { return DoubleLanes(m.m ? a.v : b.v); }

// The same two for one double, so one template serves a body and eight. (Not all and select:
// those of simd.h are in scope wherever generated code is.)
inline bool every(bool a) { return a; }
inline double pick(bool m, double a, double b) { return m ? a : b; }

}  // namespace cellphys
