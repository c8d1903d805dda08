// cellphys SIMD layer: spu-style short vectors (vf4, vf8) and the W-lane
// "SIMD scalar" Batch<W> used by generated kernels.
//
// Determinism: every operation gives the same bits on every path (avx512, avx2, scalar)
// and every run, whatever the alignment or thread count (the path is fixed at compile time).
//  * FMA is explicit only, and then fused on every path: madd/nmsub (vf4, vf8) and fma
//    (Batch, float, double) round once; the scalar path calls std::fma, which is correctly
//    rounded by definition. The build uses -ffp-contract=off, so a*b+c is never fused;
//    dot3/cross3 additionally hide their products from the optimizer, so they hold even in a
//    translation unit built without the flag.
//  * Reductions (dot3, hsum) use one fixed order, identical on all paths; a Batch<W> is W
//    independent lanes whatever the register width.
//  * min(a,b) = a<b ? a : b and max(a,b) = a>b ? a : b everywhere, matching
//    x86 minps/maxps (on ties and NaN the second operand wins).
#pragma once

#include <cmath>
#include <cstdlib>
#include <cstring>

#if defined(CELLPHYS_SIMD_SCALAR)
#define CELLPHYS_SIMD_PATH_SCALAR 1
#elif defined(__AVX512F__)  // only AVX512F is required (not VL/DQ)
#define CELLPHYS_SIMD_PATH_AVX512 1
#define CELLPHYS_SIMD_X86 1
#elif defined(__AVX2__) && defined(__FMA__)
#define CELLPHYS_SIMD_PATH_AVX2 1
#define CELLPHYS_SIMD_X86 1
#else
#define CELLPHYS_SIMD_PATH_SCALAR 1
#endif

#if defined(CELLPHYS_SIMD_X86)
#include <immintrin.h>
#endif

namespace cellphys {
namespace simd {

#if defined(CELLPHYS_SIMD_PATH_AVX512)
constexpr const char* kPathName = "avx512";
constexpr int kNativeWidth = 16;
#elif defined(CELLPHYS_SIMD_PATH_AVX2)
constexpr const char* kPathName = "avx2";
constexpr int kNativeWidth = 8;
#else
constexpr const char* kPathName = "scalar";
constexpr int kNativeWidth = 8;  // layouts stay those of the SIMD paths
#endif

// ---------------------------------------------------------------------------
// Scalar overloads: generated code does `using namespace cellphys::simd;` and
// calls sqrt/abs/fma/min/max/select unqualified with S = float or double.
// sqrt/abs/fma are using-declarations (not new functions) so they name the
// same entities as std:: and ::, which keeps calls unambiguous even when
// <math.h> or `using namespace std;` is also in scope. Mixed argument types
// (double with float literal) are ambiguous: generated code writes S(0.5).
using std::abs;
using std::fma;
using std::sqrt;
inline float select(bool m, float a, float b) { return m ? a : b; }
inline double select(bool m, double a, double b) { return m ? a : b; }
inline float min(float a, float b) { return a < b ? a : b; }
inline double min(double a, double b) { return a < b ? a : b; }
inline float max(float a, float b) { return a > b ? a : b; }
inline double max(double a, double b) { return a > b ? a : b; }
inline bool any(bool m) { return m; }
inline bool all(bool m) { return m; }

// ---------------------------------------------------------------------------
// vf4 (padded 3-vector x y z _) and vf8 (8x6 block column / padded 6-vector).
// Thin structs rather than raw __m128 so the scalar path has the same API.
#if defined(CELLPHYS_SIMD_X86)
struct alignas(16) vf4 { __m128 v; };
struct alignas(32) vf8 { __m256 v; };

namespace detail {
// -mavx512f does not imply -mfma; borrow the 512-bit FMA in that case.
inline __m128 fmadd(__m128 a, __m128 b, __m128 c) {
#if defined(__FMA__)
  return _mm_fmadd_ps(a, b, c);
#else
  return _mm512_castps512_ps128(_mm512_fmadd_ps(_mm512_castps128_ps512(a),
      _mm512_castps128_ps512(b), _mm512_castps128_ps512(c)));
#endif
}
inline __m256 fmadd(__m256 a, __m256 b, __m256 c) {
#if defined(__FMA__)
  return _mm256_fmadd_ps(a, b, c);
#else
  return _mm512_castps512_ps256(_mm512_fmadd_ps(_mm512_castps256_ps512(a),
      _mm512_castps256_ps512(b), _mm512_castps256_ps512(c)));
#endif
}
inline __m128 fnmadd(__m128 a, __m128 b, __m128 c) {
  return fmadd(_mm_xor_ps(a, _mm_set1_ps(-0.0f)), b, c);  // exact: -(a*b)+c
}
inline __m256 fnmadd(__m256 a, __m256 b, __m256 c) {
  return fmadd(_mm256_xor_ps(a, _mm256_set1_ps(-0.0f)), b, c);
}
// Hides a product from the optimizer so it cannot be contracted into an FMA
// even if a translation unit forgets -ffp-contract=off. Emits no instruction.
inline __m128 opaque(__m128 v) {
#if defined(__GNUC__)
  __asm__("" : "+x"(v));
#endif
  return v;
}
}  // namespace detail
#else
struct alignas(16) vf4 { float v[4]; };
struct alignas(32) vf8 { float v[8]; };

namespace detail {
// Scalar twin of the SIMD opaque(): keeps a*b rounded on its own even when
// the portable path is built for an FMA-capable CPU without -ffp-contract=off.
inline float opaque(float x) {
#if defined(__GNUC__) && (defined(__x86_64__) || defined(__i386__)) && defined(__SSE__)
  __asm__("" : "+x"(x));
#elif defined(__GNUC__) && defined(__aarch64__)
  __asm__("" : "+w"(x));
#endif
  return x;
}
}  // namespace detail
#endif

// splats/load/loadu take only a float, so the vector type is a template
// argument; it defaults to vf4 so spu-style `splats(x)` still reads naturally.
template <class V = vf4> V splats(float x);
template <class V = vf4> V load(const float* p);   // p aligned to sizeof(V)
template <class V = vf4> V loadu(const float* p);

#if defined(CELLPHYS_SIMD_X86)
template <> inline vf4 splats<vf4>(float x) { return {_mm_set1_ps(x)}; }
template <> inline vf4 load<vf4>(const float* p) { return {_mm_load_ps(p)}; }
template <> inline vf4 loadu<vf4>(const float* p) { return {_mm_loadu_ps(p)}; }
inline void store(float* p, vf4 a) { _mm_store_ps(p, a.v); }
inline void storeu(float* p, vf4 a) { _mm_storeu_ps(p, a.v); }
inline vf4 add(vf4 a, vf4 b) { return {_mm_add_ps(a.v, b.v)}; }
inline vf4 sub(vf4 a, vf4 b) { return {_mm_sub_ps(a.v, b.v)}; }
inline vf4 mul(vf4 a, vf4 b) { return {_mm_mul_ps(a.v, b.v)}; }
inline vf4 madd(vf4 a, vf4 b, vf4 c) { return {detail::fmadd(a.v, b.v, c.v)}; }
inline vf4 nmsub(vf4 a, vf4 b, vf4 c) { return {detail::fnmadd(a.v, b.v, c.v)}; }

template <> inline vf8 splats<vf8>(float x) { return {_mm256_set1_ps(x)}; }
template <> inline vf8 load<vf8>(const float* p) { return {_mm256_load_ps(p)}; }
template <> inline vf8 loadu<vf8>(const float* p) { return {_mm256_loadu_ps(p)}; }
inline void store(float* p, vf8 a) { _mm256_store_ps(p, a.v); }
inline void storeu(float* p, vf8 a) { _mm256_storeu_ps(p, a.v); }
inline vf8 add(vf8 a, vf8 b) { return {_mm256_add_ps(a.v, b.v)}; }
inline vf8 sub(vf8 a, vf8 b) { return {_mm256_sub_ps(a.v, b.v)}; }
inline vf8 mul(vf8 a, vf8 b) { return {_mm256_mul_ps(a.v, b.v)}; }
inline vf8 madd(vf8 a, vf8 b, vf8 c) { return {detail::fmadd(a.v, b.v, c.v)}; }
inline vf8 nmsub(vf8 a, vf8 b, vf8 c) { return {detail::fnmadd(a.v, b.v, c.v)}; }
// (a0, ..., a7) built in registers: eight floats stored and loaded back as one vector wait
// for their stores to drain (a failed store-to-load forward, each time).
inline vf8 vf8_of(float a0, float a1, float a2, float a3, float a4, float a5, float a6, float a7) {
  return {_mm256_setr_ps(a0, a1, a2, a3, a4, a5, a6, a7)};
}

template <int i0, int i1, int i2, int i3>
inline vf4 shuffle(vf4 a) {
  static_assert(i0 >= 0 && i0 < 4 && i1 >= 0 && i1 < 4 && i2 >= 0 && i2 < 4 &&
                i3 >= 0 && i3 < 4, "shuffle lane index out of range");
  return {_mm_shuffle_ps(a.v, a.v, _MM_SHUFFLE(i3, i2, i1, i0))};
}

// (x*x' + y*y') + z*z', no FMA: same bits as the scalar path.
inline float dot3(vf4 a, vf4 b) {
  __m128 p = detail::opaque(_mm_mul_ps(a.v, b.v));
  __m128 s = _mm_add_ss(p, _mm_shuffle_ps(p, p, _MM_SHUFFLE(1, 1, 1, 1)));
  return _mm_cvtss_f32(_mm_add_ss(s, _mm_movehl_ps(p, p)));
}

// a.yzx*b.zxy - a.zxy*b.yzx; lane 3 forced to 0 even for inf/NaN padding.
inline vf4 cross3(vf4 a, vf4 b) {
  __m128 a1 = _mm_shuffle_ps(a.v, a.v, _MM_SHUFFLE(3, 0, 2, 1));
  __m128 b1 = _mm_shuffle_ps(b.v, b.v, _MM_SHUFFLE(3, 1, 0, 2));
  __m128 a2 = _mm_shuffle_ps(a.v, a.v, _MM_SHUFFLE(3, 1, 0, 2));
  __m128 b2 = _mm_shuffle_ps(b.v, b.v, _MM_SHUFFLE(3, 0, 2, 1));
  __m128 c = _mm_sub_ps(detail::opaque(_mm_mul_ps(a1, b1)),
                        detail::opaque(_mm_mul_ps(a2, b2)));
  return {_mm_blend_ps(c, _mm_setzero_ps(), 0x8)};
}

// ((l0+l4)+(l2+l6)) + ((l1+l5)+(l3+l7)); the scalar path uses the same order.
inline float hsum(vf8 a) {
  __m128 s = _mm_add_ps(_mm256_castps256_ps128(a.v), _mm256_extractf128_ps(a.v, 1));
  __m128 t = _mm_add_ps(s, _mm_movehl_ps(s, s));
  return _mm_cvtss_f32(_mm_add_ss(t, _mm_shuffle_ps(t, t, _MM_SHUFFLE(1, 1, 1, 1))));
}

// 8x8 transpose: out[c] lane r = rows[r][c], in registers. Moves a structure-of-arrays batch
// (one row per quantity, one lane per force) into one 8-float column per force. Pure data
// movement.
inline void transpose8(const float* const rows[8], vf8 out[8]) {
  __m256 r[8], t[8];
  for (int i = 0; i < 8; ++i) r[i] = _mm256_loadu_ps(rows[i]);
  for (int i = 0; i < 8; i += 2) {
    t[i] = _mm256_unpacklo_ps(r[i], r[i + 1]);
    t[i + 1] = _mm256_unpackhi_ps(r[i], r[i + 1]);
  }
  for (int i = 0; i < 8; i += 4) {
    r[i] = _mm256_shuffle_ps(t[i], t[i + 2], _MM_SHUFFLE(1, 0, 1, 0));
    r[i + 1] = _mm256_shuffle_ps(t[i], t[i + 2], _MM_SHUFFLE(3, 2, 3, 2));
    r[i + 2] = _mm256_shuffle_ps(t[i + 1], t[i + 3], _MM_SHUFFLE(1, 0, 1, 0));
    r[i + 3] = _mm256_shuffle_ps(t[i + 1], t[i + 3], _MM_SHUFFLE(3, 2, 3, 2));
  }
  for (int i = 0; i < 4; ++i) {
    out[i].v = _mm256_permute2f128_ps(r[i], r[i + 4], 0x20);
    out[i + 4].v = _mm256_permute2f128_ps(r[i], r[i + 4], 0x31);
  }
}
// The same into memory: out[8c + r] = rows[r][c].
inline void transpose8(const float* const rows[8], float* out) {
  vf8 columns[8];
  transpose8(rows, columns);
  for (int c = 0; c < 8; ++c) _mm256_storeu_ps(out + 8 * c, columns[c].v);
}
#else   // scalar path
template <> inline vf4 splats<vf4>(float x) { return {{x, x, x, x}}; }
template <> inline vf4 load<vf4>(const float* p) { vf4 r; std::memcpy(r.v, p, sizeof r.v); return r; }
template <> inline vf4 loadu<vf4>(const float* p) { return load<vf4>(p); }
template <> inline vf8 splats<vf8>(float x) { return {{x, x, x, x, x, x, x, x}}; }
template <> inline vf8 load<vf8>(const float* p) { vf8 r; std::memcpy(r.v, p, sizeof r.v); return r; }
template <> inline vf8 loadu<vf8>(const float* p) { return load<vf8>(p); }

#define CELLPHYS_SIMD_SCALAR_VEC_OPS(V, N)                                     \
  inline void store(float* p, V a) { std::memcpy(p, a.v, sizeof a.v); }       \
  inline void storeu(float* p, V a) { std::memcpy(p, a.v, sizeof a.v); }      \
  inline V add(V a, V b) { for (int i = 0; i < N; ++i) a.v[i] += b.v[i]; return a; } \
  inline V sub(V a, V b) { for (int i = 0; i < N; ++i) a.v[i] -= b.v[i]; return a; } \
  inline V mul(V a, V b) { for (int i = 0; i < N; ++i) a.v[i] *= b.v[i]; return a; } \
  inline V madd(V a, V b, V c) {                                               \
    for (int i = 0; i < N; ++i) c.v[i] = std::fma(a.v[i], b.v[i], c.v[i]);     \
    return c;                                                                  \
  }                                                                            \
  inline V nmsub(V a, V b, V c) {                                              \
    for (int i = 0; i < N; ++i) c.v[i] = std::fma(-a.v[i], b.v[i], c.v[i]);    \
    return c;                                                                  \
  }
CELLPHYS_SIMD_SCALAR_VEC_OPS(vf4, 4)
CELLPHYS_SIMD_SCALAR_VEC_OPS(vf8, 8)
#undef CELLPHYS_SIMD_SCALAR_VEC_OPS
inline vf8 vf8_of(float a0, float a1, float a2, float a3, float a4, float a5, float a6, float a7) {
  return {{a0, a1, a2, a3, a4, a5, a6, a7}};
}

template <int i0, int i1, int i2, int i3>
inline vf4 shuffle(vf4 a) {
  static_assert(i0 >= 0 && i0 < 4 && i1 >= 0 && i1 < 4 && i2 >= 0 && i2 < 4 &&
                i3 >= 0 && i3 < 4, "shuffle lane index out of range");
  return {{a.v[i0], a.v[i1], a.v[i2], a.v[i3]}};
}
inline float dot3(vf4 a, vf4 b) {
  using detail::opaque;
  return (opaque(a.v[0] * b.v[0]) + opaque(a.v[1] * b.v[1])) + opaque(a.v[2] * b.v[2]);
}
inline vf4 cross3(vf4 a, vf4 b) {
  using detail::opaque;
  return {{opaque(a.v[1] * b.v[2]) - opaque(a.v[2] * b.v[1]),
           opaque(a.v[2] * b.v[0]) - opaque(a.v[0] * b.v[2]),
           opaque(a.v[0] * b.v[1]) - opaque(a.v[1] * b.v[0]), 0.0f}};
}
inline float hsum(vf8 a) {
  const float* l = a.v;
  return ((l[0] + l[4]) + (l[2] + l[6])) + ((l[1] + l[5]) + (l[3] + l[7]));
}
inline void transpose8(const float* const rows[8], vf8 out[8]) {
  for (int r = 0; r < 8; ++r)
    for (int c = 0; c < 8; ++c) out[c].v[r] = rows[r][c];
}
inline void transpose8(const float* const rows[8], float* out) {
  for (int r = 0; r < 8; ++r)
    for (int c = 0; c < 8; ++c) out[8 * c + r] = rows[r][c];
}
#endif

// Lane access by runtime index; through memory so it is one code path.
inline float extract(vf4 a, int i) { float f[4]; std::memcpy(f, &a.v, sizeof f); return f[i]; }
inline float extract(vf8 a, int i) { float f[8]; std::memcpy(f, &a.v, sizeof f); return f[i]; }
inline vf4 insert(vf4 a, int i, float x) {
  float f[4]; std::memcpy(f, &a.v, sizeof f); f[i] = x; std::memcpy(&a.v, f, sizeof f); return a;
}
inline vf8 insert(vf8 a, int i, float x) {
  float f[8]; std::memcpy(f, &a.v, sizeof f); f[i] = x; std::memcpy(&a.v, f, sizeof f); return a;
}

// ---------------------------------------------------------------------------
// Batch<W>: W independent lanes behaving like one float. Built from N = W/L
// native registers of L lanes each; detail::Reg<L> is the per-register ISA.
namespace detail {
template <int L> struct Reg;

template <> struct Reg<1> {  // portable: one float per "register"
  using T = float;
  using M = bool;
  static T set1(float x) { return x; }
  static T load(const float* p) { return *p; }
  static T loadu(const float* p) { return *p; }
  static void store(float* p, T a) { *p = a; }
  static void storeu(float* p, T a) { *p = a; }
  static T add(T a, T b) { return a + b; }
  static T sub(T a, T b) { return a - b; }
  static T mul(T a, T b) { return a * b; }
  static T div(T a, T b) { return a / b; }
  static T neg(T a) { return -a; }
  static T fma(T a, T b, T c) { return std::fma(a, b, c); }
  static T sqrt(T a) { return std::sqrt(a); }
  static T abs(T a) { return std::fabs(a); }
  static T min(T a, T b) { return a < b ? a : b; }
  static T max(T a, T b) { return a > b ? a : b; }
  static M lt(T a, T b) { return a < b; }
  static M le(T a, T b) { return a <= b; }
  static M gt(T a, T b) { return a > b; }
  static M ge(T a, T b) { return a >= b; }
  static T blend(M m, T a, T b) { return m ? a : b; }
  static M mand(M a, M b) { return a && b; }
  static M mor(M a, M b) { return a || b; }
  static M mnot(M a) { return !a; }
  static int bits(M m) { return m ? 1 : 0; }
};

#if defined(CELLPHYS_SIMD_X86)
template <> struct Reg<4> {  // masks are all-ones/all-zeros lanes (cmpps)
  using T = __m128;
  using M = __m128;
  static T set1(float x) { return _mm_set1_ps(x); }
  static T load(const float* p) { return _mm_load_ps(p); }
  static T loadu(const float* p) { return _mm_loadu_ps(p); }
  static void store(float* p, T a) { _mm_store_ps(p, a); }
  static void storeu(float* p, T a) { _mm_storeu_ps(p, a); }
  static T add(T a, T b) { return _mm_add_ps(a, b); }
  static T sub(T a, T b) { return _mm_sub_ps(a, b); }
  static T mul(T a, T b) { return _mm_mul_ps(a, b); }
  static T div(T a, T b) { return _mm_div_ps(a, b); }
  static T neg(T a) { return _mm_xor_ps(a, _mm_set1_ps(-0.0f)); }
  static T fma(T a, T b, T c) { return fmadd(a, b, c); }
  static T sqrt(T a) { return _mm_sqrt_ps(a); }
  static T abs(T a) { return _mm_andnot_ps(_mm_set1_ps(-0.0f), a); }
  static T min(T a, T b) { return _mm_min_ps(a, b); }
  static T max(T a, T b) { return _mm_max_ps(a, b); }
  static M lt(T a, T b) { return _mm_cmp_ps(a, b, _CMP_LT_OQ); }
  static M le(T a, T b) { return _mm_cmp_ps(a, b, _CMP_LE_OQ); }
  static M gt(T a, T b) { return _mm_cmp_ps(a, b, _CMP_GT_OQ); }
  static M ge(T a, T b) { return _mm_cmp_ps(a, b, _CMP_GE_OQ); }
  // and/andnot/or, not blendv: GCC 12 with -mavx512vl miscompiles (or ICEs
  // on) _mm_blendv_ps fed by a compare; masks are whole lanes, so exact.
  static T blend(M m, T a, T b) { return _mm_or_ps(_mm_and_ps(m, a), _mm_andnot_ps(m, b)); }
  static M mand(M a, M b) { return _mm_and_ps(a, b); }
  static M mor(M a, M b) { return _mm_or_ps(a, b); }
  static M mnot(M a) { return _mm_xor_ps(a, _mm_castsi128_ps(_mm_set1_epi32(-1))); }
  static int bits(M m) { return _mm_movemask_ps(m); }
};

template <> struct Reg<8> {
  using T = __m256;
  using M = __m256;
  static T set1(float x) { return _mm256_set1_ps(x); }
  static T load(const float* p) { return _mm256_load_ps(p); }
  static T loadu(const float* p) { return _mm256_loadu_ps(p); }
  static void store(float* p, T a) { _mm256_store_ps(p, a); }
  static void storeu(float* p, T a) { _mm256_storeu_ps(p, a); }
  static T add(T a, T b) { return _mm256_add_ps(a, b); }
  static T sub(T a, T b) { return _mm256_sub_ps(a, b); }
  static T mul(T a, T b) { return _mm256_mul_ps(a, b); }
  static T div(T a, T b) { return _mm256_div_ps(a, b); }
  static T neg(T a) { return _mm256_xor_ps(a, _mm256_set1_ps(-0.0f)); }
  static T fma(T a, T b, T c) { return fmadd(a, b, c); }
  static T sqrt(T a) { return _mm256_sqrt_ps(a); }
  static T abs(T a) { return _mm256_andnot_ps(_mm256_set1_ps(-0.0f), a); }
  static T min(T a, T b) { return _mm256_min_ps(a, b); }
  static T max(T a, T b) { return _mm256_max_ps(a, b); }
  static M lt(T a, T b) { return _mm256_cmp_ps(a, b, _CMP_LT_OQ); }
  static M le(T a, T b) { return _mm256_cmp_ps(a, b, _CMP_LE_OQ); }
  static M gt(T a, T b) { return _mm256_cmp_ps(a, b, _CMP_GT_OQ); }
  static M ge(T a, T b) { return _mm256_cmp_ps(a, b, _CMP_GE_OQ); }
  static T blend(M m, T a, T b) {  // see Reg<4>::blend
    return _mm256_or_ps(_mm256_and_ps(m, a), _mm256_andnot_ps(m, b));
  }
  static M mand(M a, M b) { return _mm256_and_ps(a, b); }
  static M mor(M a, M b) { return _mm256_or_ps(a, b); }
  static M mnot(M a) { return _mm256_xor_ps(a, _mm256_castsi256_ps(_mm256_set1_epi32(-1))); }
  static int bits(M m) { return _mm256_movemask_ps(m); }
};
#endif

#if defined(CELLPHYS_SIMD_PATH_AVX512)
template <> struct Reg<16> {  // masks are k-registers; only AVX512F needed
  using T = __m512;
  using M = __mmask16;
  static __m512i sign() { return _mm512_set1_epi32(static_cast<int>(0x80000000u)); }
  static T set1(float x) { return _mm512_set1_ps(x); }
  static T load(const float* p) { return _mm512_load_ps(p); }
  static T loadu(const float* p) { return _mm512_loadu_ps(p); }
  static void store(float* p, T a) { _mm512_store_ps(p, a); }
  static void storeu(float* p, T a) { _mm512_storeu_ps(p, a); }
  static T add(T a, T b) { return _mm512_add_ps(a, b); }
  static T sub(T a, T b) { return _mm512_sub_ps(a, b); }
  static T mul(T a, T b) { return _mm512_mul_ps(a, b); }
  static T div(T a, T b) { return _mm512_div_ps(a, b); }
  static T neg(T a) {  // _mm512_xor_ps would need AVX512DQ
    return _mm512_castsi512_ps(_mm512_xor_si512(_mm512_castps_si512(a), sign()));
  }
  static T fma(T a, T b, T c) { return _mm512_fmadd_ps(a, b, c); }
  // Full-mask forms: GCC 12's unmasked ones trip -Wmaybe-uninitialized.
  static T sqrt(T a) { return _mm512_mask_sqrt_ps(a, 0xFFFF, a); }
  static T abs(T a) { return _mm512_abs_ps(a); }
  static T min(T a, T b) { return _mm512_mask_min_ps(a, 0xFFFF, a, b); }
  static T max(T a, T b) { return _mm512_mask_max_ps(a, 0xFFFF, a, b); }
  static M lt(T a, T b) { return _mm512_cmp_ps_mask(a, b, _CMP_LT_OQ); }
  static M le(T a, T b) { return _mm512_cmp_ps_mask(a, b, _CMP_LE_OQ); }
  static M gt(T a, T b) { return _mm512_cmp_ps_mask(a, b, _CMP_GT_OQ); }
  static M ge(T a, T b) { return _mm512_cmp_ps_mask(a, b, _CMP_GE_OQ); }
  static T blend(M m, T a, T b) { return _mm512_mask_blend_ps(m, b, a); }
  static M mand(M a, M b) { return static_cast<M>(a & b); }
  static M mor(M a, M b) { return static_cast<M>(a | b); }
  static M mnot(M a) { return static_cast<M>(~a); }
  static int bits(M m) { return m; }
};
#endif

// Lanes per native register used for a Batch<W> on this path.
template <int W> constexpr int reg_lanes() {
#if defined(CELLPHYS_SIMD_PATH_AVX512)
  return W;
#elif defined(CELLPHYS_SIMD_PATH_AVX2)
  return W < 8 ? W : 8;
#else
  return 1;
#endif
}
}  // namespace detail

// Per-lane boolean produced by Batch comparisons; consumed by select.
template <int W> struct Mask {
  static constexpr int L = detail::reg_lanes<W>();
  static constexpr int N = W / L;
  using R = detail::Reg<L>;
  typename R::M m[N];

  bool operator[](int i) const { return (R::bits(m[i / L]) >> (i % L)) & 1; }
  friend Mask operator&(const Mask& a, const Mask& b) {
    Mask r; for (int i = 0; i < N; ++i) r.m[i] = R::mand(a.m[i], b.m[i]); return r;
  }
  friend Mask operator|(const Mask& a, const Mask& b) {
    Mask r; for (int i = 0; i < N; ++i) r.m[i] = R::mor(a.m[i], b.m[i]); return r;
  }
  friend Mask operator!(const Mask& a) {
    Mask r; for (int i = 0; i < N; ++i) r.m[i] = R::mnot(a.m[i]); return r;
  }
  friend bool any(const Mask& a) {
    for (int i = 0; i < N; ++i) if (R::bits(a.m[i])) return true;
    return false;
  }
  friend bool all(const Mask& a) {
    for (int i = 0; i < N; ++i) if (R::bits(a.m[i]) != (1 << L) - 1) return false;
    return true;
  }
};

// Named functions are hidden friends: found by ADL for unqualified calls,
// and float arguments convert implicitly (min(x, 0.0f), fma(a, b, 1.0f)).
template <int W> struct alignas(4 * W) Batch {
  static_assert(W == 4 || W == 8 || W == 16, "Batch width must be 4, 8 or 16");
  static constexpr int kWidth = W;
  static constexpr int L = detail::reg_lanes<W>();
  static constexpr int N = W / L;
  using R = detail::Reg<L>;
  typename R::T r[N];

  Batch() : Batch(0.0f) {}
  Batch(float x) { for (int i = 0; i < N; ++i) r[i] = R::set1(x); }  // NOLINT: implicit by design

  static Batch load(const float* p) {  // p aligned to 4*W bytes
    Batch b; for (int i = 0; i < N; ++i) b.r[i] = R::load(p + i * L); return b;
  }
  static Batch loadu(const float* p) {
    Batch b; for (int i = 0; i < N; ++i) b.r[i] = R::loadu(p + i * L); return b;
  }
  void store(float* p) const { for (int i = 0; i < N; ++i) R::store(p + i * L, r[i]); }
  void storeu(float* p) const { for (int i = 0; i < N; ++i) R::storeu(p + i * L, r[i]); }

  // Lane access (not for hot loops): registers are plain lane-ordered floats.
  float operator[](int lane) const {
    float f[W]; std::memcpy(f, r, sizeof f); return f[lane];
  }
  void set(int lane, float x) {
    float f[W]; std::memcpy(f, r, sizeof f); f[lane] = x; std::memcpy(r, f, sizeof f);
  }

 private:
  template <class F> static Batch map(F f) {
    Batch b; for (int i = 0; i < N; ++i) b.r[i] = f(i); return b;
  }
  template <class F> static Mask<W> cmp(F f) {
    Mask<W> m; for (int i = 0; i < N; ++i) m.m[i] = f(i); return m;
  }

 public:
  friend Batch operator+(const Batch& a, const Batch& b) { return map([&](int i) { return R::add(a.r[i], b.r[i]); }); }
  friend Batch operator-(const Batch& a, const Batch& b) { return map([&](int i) { return R::sub(a.r[i], b.r[i]); }); }
  friend Batch operator*(const Batch& a, const Batch& b) { return map([&](int i) { return R::mul(a.r[i], b.r[i]); }); }
  friend Batch operator/(const Batch& a, const Batch& b) { return map([&](int i) { return R::div(a.r[i], b.r[i]); }); }
  friend Batch operator-(const Batch& a) { return map([&](int i) { return R::neg(a.r[i]); }); }
  Batch& operator+=(const Batch& b) { return *this = *this + b; }
  Batch& operator-=(const Batch& b) { return *this = *this - b; }
  Batch& operator*=(const Batch& b) { return *this = *this * b; }
  Batch& operator/=(const Batch& b) { return *this = *this / b; }

  // Ordered, quiet comparisons: false on NaN, like float.
  friend Mask<W> operator<(const Batch& a, const Batch& b) { return cmp([&](int i) { return R::lt(a.r[i], b.r[i]); }); }
  friend Mask<W> operator<=(const Batch& a, const Batch& b) { return cmp([&](int i) { return R::le(a.r[i], b.r[i]); }); }
  friend Mask<W> operator>(const Batch& a, const Batch& b) { return cmp([&](int i) { return R::gt(a.r[i], b.r[i]); }); }
  friend Mask<W> operator>=(const Batch& a, const Batch& b) { return cmp([&](int i) { return R::ge(a.r[i], b.r[i]); }); }

  friend Batch select(const Mask<W>& m, const Batch& a, const Batch& b) {
    return map([&](int i) { return R::blend(m.m[i], a.r[i], b.r[i]); });
  }
  friend Batch sqrt(const Batch& a) { return map([&](int i) { return R::sqrt(a.r[i]); }); }
  friend Batch abs(const Batch& a) { return map([&](int i) { return R::abs(a.r[i]); }); }
  friend Batch min(const Batch& a, const Batch& b) { return map([&](int i) { return R::min(a.r[i], b.r[i]); }); }
  friend Batch max(const Batch& a, const Batch& b) { return map([&](int i) { return R::max(a.r[i], b.r[i]); }); }
  friend Batch fma(const Batch& a, const Batch& b, const Batch& c) {
    return map([&](int i) { return R::fma(a.r[i], b.r[i], c.r[i]); });
  }
};

// ---------------------------------------------------------------------------
// angle_of(y, x): atan2 in [-pi, pi] for S = float, double or Batch<W>, from IEEE add,
// multiply, divide, compare and select only, so it gives the same bits on every path
// (the C library's atan2 need not). The generated kernels call it for joint angles.
// Reduction to t = min/max in [0, 1], then to |u| <= tan(pi/8) by atan t = pi/4 +
// atan((t-1)/(t+1)), then the odd Taylor series to u^23 (truncation < 1e-11 there).
// atan2(0, 0) is 0; -0 is treated as +0.
template <class S> struct LaneType { using T = S; };
template <int W> struct LaneType<Batch<W>> { using T = float; };

template <class S> S angle_of(S y, S x) {
  using T = typename LaneType<S>::T;
  const S zero = S(T(0)), one = S(T(1));
  const S ax = abs(x), ay = abs(y);
  const S hi = max(ax, ay), lo = min(ax, ay);
  const S t = select(hi > zero, lo / select(hi > zero, hi, one), zero);
  const auto big = t > S(T(0.41421356237309503));  // tan(pi/8)
  const S u = select(big, (t - one) / (t + one), t);
  const S z = u * u;
  S p = S(T(-1.0 / 23));
  p = p * z + S(T(1.0 / 21));
  p = p * z + S(T(-1.0 / 19));
  p = p * z + S(T(1.0 / 17));
  p = p * z + S(T(-1.0 / 15));
  p = p * z + S(T(1.0 / 13));
  p = p * z + S(T(-1.0 / 11));
  p = p * z + S(T(1.0 / 9));
  p = p * z + S(T(-1.0 / 7));
  p = p * z + S(T(1.0 / 5));
  p = p * z + S(T(-1.0 / 3));
  S r = u + u * (z * p);
  r = select(big, S(T(0.78539816339744831)) + r, r);
  r = select(ay > ax, S(T(1.5707963267948966)) - r, r);
  r = select(x < zero, S(T(3.1415926535897932)) - r, r);
  return select(y < zero, -r, r);
}

}  // namespace simd
}  // namespace cellphys
