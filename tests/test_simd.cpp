// Tests for runtime/base/simd.h on whichever path the build selects
// (CELLPHYS_SIMD_SCALAR, AVX2+FMA or AVX-512).
#include <math.h>  // also puts std::sqrt etc. into :: (ambiguity check below)

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <random>

#include "runtime/base/simd.h"

namespace {

namespace sd = cellphys::simd;
using sd::Batch;
using sd::vf4;
using sd::vf8;

std::uint32_t bits(float f) { std::uint32_t u; std::memcpy(&u, &f, 4); return u; }

// A product rounded to float on its own: a call result cannot be contracted
// into an FMA, so hand formulas stay two-rounding even without
// -ffp-contract=off (the project build sets it; hand compiles may not).
[[gnu::noinline]] float rmul(float a, float b) { return a * b; }

// Relative tolerance for FMA vs. two-rounding reference ("1 ulp-ish").
void expect_rel_near(float expected, float actual) {
  EXPECT_NEAR(expected, actual, 1e-6f * std::max(1.0f, std::fabs(expected)));
}

struct Rng {
  std::mt19937 gen{12345u};
  std::uniform_real_distribution<float> dist{-10.0f, 10.0f};
  float operator()() { return dist(gen); }
  template <int N> void fill(float (&a)[N]) { for (float& x : a) x = (*this)(); }
};

constexpr int kIters = 200;

// ---------------------------------------------------------------- path/layout

TEST(SimdPath, PathNameAndNativeWidthMatchCompileFlags) {
  RecordProperty("simd_path", sd::kPathName);
#if defined(CELLPHYS_SIMD_SCALAR)
  EXPECT_STREQ("scalar", sd::kPathName);
  EXPECT_EQ(8, sd::kNativeWidth);
#elif defined(__AVX512F__)
  EXPECT_STREQ("avx512", sd::kPathName);
  EXPECT_EQ(16, sd::kNativeWidth);
#elif defined(__AVX2__) && defined(__FMA__)
  EXPECT_STREQ("avx2", sd::kPathName);
  EXPECT_EQ(8, sd::kNativeWidth);
#endif
}

TEST(SimdLayout, TypesHaveRequiredAlignmentAndSize) {
  static_assert(alignof(vf4) == 16 && sizeof(vf4) == 16, "vf4 layout");
  static_assert(alignof(vf8) == 32 && sizeof(vf8) == 32, "vf8 layout");
  static_assert(alignof(Batch<4>) == 16 && sizeof(Batch<4>) == 16, "Batch<4> layout");
  static_assert(alignof(Batch<8>) == 32 && sizeof(Batch<8>) == 32, "Batch<8> layout");
  static_assert(alignof(Batch<16>) == 64 && sizeof(Batch<16>) == 64, "Batch<16> layout");
  SUCCEED();
}

// ---------------------------------------------------------------------- vf4

TEST(SimdVf4, SplatsLoadStoreRoundTripExactly) {
  alignas(16) float a[4] = {1.5f, -2.0f, 3.25f, 7.0f};
  alignas(16) float out[4];
  sd::store(out, sd::load(a));
  for (int i = 0; i < 4; ++i) EXPECT_EQ(a[i], out[i]);
  float un[5] = {0, 4, 5, 6, 7};
  sd::storeu(un + 1, sd::loadu(a));
  for (int i = 0; i < 4; ++i) EXPECT_EQ(a[i], un[i + 1]);
  vf4 s = sd::loadu(un + 1);
  for (int i = 0; i < 4; ++i) EXPECT_EQ(a[i], sd::extract(s, i));
  vf4 k = sd::splats(2.5f);
  for (int i = 0; i < 4; ++i) EXPECT_EQ(2.5f, sd::extract(k, i));
}

TEST(SimdVf4, AddSubMulExactMaddNmsubFused) {
  Rng rng;
  for (int it = 0; it < kIters; ++it) {
    alignas(16) float a[4], b[4], c[4];
    rng.fill(a); rng.fill(b); rng.fill(c);
    vf4 va = sd::load(a), vb = sd::load(b), vc = sd::load(c);
    for (int i = 0; i < 4; ++i) {
      EXPECT_EQ(a[i] + b[i], sd::extract(sd::add(va, vb), i));
      EXPECT_EQ(a[i] - b[i], sd::extract(sd::sub(va, vb), i));
      EXPECT_EQ(a[i] * b[i], sd::extract(sd::mul(va, vb), i));
      // fused, one rounding, on every path: the same bits as the correctly rounded std::fma
      EXPECT_EQ(bits(std::fma(a[i], b[i], c[i])), bits(sd::extract(sd::madd(va, vb, vc), i)));
      EXPECT_EQ(bits(std::fma(-a[i], b[i], c[i])), bits(sd::extract(sd::nmsub(va, vb, vc), i)));
    }
  }
}

TEST(SimdVf4, ShuffleInsertExtractMoveTheRightLanes) {
  alignas(16) float a[4] = {10, 11, 12, 13};
  vf4 v = sd::load(a);
  vf4 s = sd::shuffle<3, 0, 2, 1>(v);
  EXPECT_EQ(13.0f, sd::extract(s, 0));
  EXPECT_EQ(10.0f, sd::extract(s, 1));
  EXPECT_EQ(12.0f, sd::extract(s, 2));
  EXPECT_EQ(11.0f, sd::extract(s, 3));
  vf4 b = sd::shuffle<2, 2, 2, 2>(v);
  for (int i = 0; i < 4; ++i) EXPECT_EQ(12.0f, sd::extract(b, i));
  for (int lane = 0; lane < 4; ++lane) {
    vf4 w = sd::insert(v, lane, -1.0f);
    for (int i = 0; i < 4; ++i) EXPECT_EQ(i == lane ? -1.0f : a[i], sd::extract(w, i));
  }
}

TEST(SimdVf4, Dot3IgnoresLane3AndMatchesFixedOrderFormula) {
  Rng rng;
  for (int it = 0; it < kIters; ++it) {
    alignas(16) float a[4], b[4];
    rng.fill(a); rng.fill(b);
    a[3] = std::numeric_limits<float>::quiet_NaN();  // padding must not leak
    float ref = (rmul(a[0], b[0]) + rmul(a[1], b[1])) + rmul(a[2], b[2]);
    EXPECT_EQ(bits(ref), bits(sd::dot3(sd::load(a), sd::load(b))));
  }
}

TEST(SimdVf4, Cross3MatchesHandFormulaWithZeroLane3) {
  Rng rng;
  for (int it = 0; it < kIters; ++it) {
    alignas(16) float a[4], b[4];
    rng.fill(a); rng.fill(b);
    a[3] = std::numeric_limits<float>::infinity();  // padding must not leak
    vf4 c = sd::cross3(sd::load(a), sd::load(b));
    EXPECT_EQ(rmul(a[1], b[2]) - rmul(a[2], b[1]), sd::extract(c, 0));
    EXPECT_EQ(rmul(a[2], b[0]) - rmul(a[0], b[2]), sd::extract(c, 1));
    EXPECT_EQ(rmul(a[0], b[1]) - rmul(a[1], b[0]), sd::extract(c, 2));
    EXPECT_EQ(0.0f, sd::extract(c, 3));
  }
}

// ---------------------------------------------------------------------- vf8

TEST(SimdVf8, LoadStoreSplatsInsertExtractRoundTrip) {
  alignas(32) float a[8] = {1, 2, 3, 4, 5, 6, 7, 8};
  alignas(32) float out[8];
  vf8 v = sd::load<vf8>(a);
  sd::store(out, v);
  for (int i = 0; i < 8; ++i) EXPECT_EQ(a[i], out[i]);
  float un[9];
  sd::storeu(un + 1, sd::loadu<vf8>(a));
  for (int i = 0; i < 8; ++i) EXPECT_EQ(a[i], un[i + 1]);
  vf8 k = sd::splats<vf8>(-3.0f);
  for (int i = 0; i < 8; ++i) EXPECT_EQ(-3.0f, sd::extract(k, i));
  for (int lane = 0; lane < 8; ++lane) {
    vf8 w = sd::insert(v, lane, 42.0f);
    for (int i = 0; i < 8; ++i) EXPECT_EQ(i == lane ? 42.0f : a[i], sd::extract(w, i));
  }
}

TEST(SimdVf8, AddSubMulExactMaddNmsubFused) {
  Rng rng;
  for (int it = 0; it < kIters; ++it) {
    alignas(32) float a[8], b[8], c[8];
    rng.fill(a); rng.fill(b); rng.fill(c);
    vf8 va = sd::load<vf8>(a), vb = sd::load<vf8>(b), vc = sd::load<vf8>(c);
    for (int i = 0; i < 8; ++i) {
      EXPECT_EQ(a[i] + b[i], sd::extract(sd::add(va, vb), i));
      EXPECT_EQ(a[i] - b[i], sd::extract(sd::sub(va, vb), i));
      EXPECT_EQ(a[i] * b[i], sd::extract(sd::mul(va, vb), i));
      // fused, one rounding, on every path: the same bits as the correctly rounded std::fma
      EXPECT_EQ(bits(std::fma(a[i], b[i], c[i])), bits(sd::extract(sd::madd(va, vb, vc), i)));
      EXPECT_EQ(bits(std::fma(-a[i], b[i], c[i])), bits(sd::extract(sd::nmsub(va, vb, vc), i)));
    }
  }
}

TEST(SimdVf8, HsumUsesDocumentedPairwiseOrderBitExactly) {
  Rng rng;
  for (int it = 0; it < kIters; ++it) {
    alignas(32) float l[8];
    rng.fill(l);
    float ref = ((l[0] + l[4]) + (l[2] + l[6])) + ((l[1] + l[5]) + (l[3] + l[7]));
    float got = sd::hsum(sd::load<vf8>(l));
    EXPECT_EQ(bits(ref), bits(got));
    EXPECT_EQ(bits(got), bits(sd::hsum(sd::load<vf8>(l))));  // repeatable
  }
}

// -------------------------------------------------------------------- Batch

template <class T> class SimdBatch : public ::testing::Test {};
using BatchTypes = ::testing::Types<Batch<4>, Batch<8>, Batch<16>>;
TYPED_TEST_SUITE(SimdBatch, BatchTypes);

TYPED_TEST(SimdBatch, ConstructLoadStoreLaneAccessRoundTrip) {
  using B = TypeParam;
  constexpr int W = B::kWidth;
  B z;
  B k(1.5f);
  for (int i = 0; i < W; ++i) { EXPECT_EQ(0.0f, z[i]); EXPECT_EQ(1.5f, k[i]); }
  alignas(64) float a[W], out[W];
  for (int i = 0; i < W; ++i) a[i] = 0.5f * i - 3.0f;
  B v = B::load(a);
  v.store(out);
  for (int i = 0; i < W; ++i) { EXPECT_EQ(a[i], out[i]); EXPECT_EQ(a[i], v[i]); }
  float un[W + 1];
  B::loadu(a).storeu(un + 1);
  for (int i = 0; i < W; ++i) EXPECT_EQ(a[i], un[i + 1]);
  EXPECT_EQ(a[W - 1], B::loadu(un + 1)[W - 1]);
  v.set(W - 2, 99.0f);
  for (int i = 0; i < W; ++i) EXPECT_EQ(i == W - 2 ? 99.0f : a[i], v[i]);
}

TYPED_TEST(SimdBatch, ArithmeticOperatorsMatchPerLaneFloatExactly) {
  using B = TypeParam;
  constexpr int W = B::kWidth;
  Rng rng;
  for (int it = 0; it < kIters; ++it) {
    alignas(64) float a[W], b[W];
    for (int i = 0; i < W; ++i) { a[i] = rng(); b[i] = rng(); }
    const float s = rng();
    B x = B::load(a), y = B::load(b);
    B add = x + y, sub = x - y, mul = x * y, div = x / y, neg = -x;
    B adds = x + s, sadd = s + x, subs = x - s, ssub = s - x;
    B muls = x * s, smul = s * x, divs = x / s, sdiv = s / x;
    B ca = x, cs = x, cm = x, cd = x;
    ca += y; cs -= y; cm *= y; cd /= y;
    for (int i = 0; i < W; ++i) {
      EXPECT_EQ(a[i] + b[i], add[i]);
      EXPECT_EQ(a[i] - b[i], sub[i]);
      EXPECT_EQ(a[i] * b[i], mul[i]);
      EXPECT_EQ(a[i] / b[i], div[i]);
      EXPECT_EQ(bits(-a[i]), bits(neg[i]));
      EXPECT_EQ(a[i] + s, adds[i]);
      EXPECT_EQ(s + a[i], sadd[i]);
      EXPECT_EQ(a[i] - s, subs[i]);
      EXPECT_EQ(s - a[i], ssub[i]);
      EXPECT_EQ(a[i] * s, muls[i]);
      EXPECT_EQ(s * a[i], smul[i]);
      EXPECT_EQ(a[i] / s, divs[i]);
      EXPECT_EQ(s / a[i], sdiv[i]);
      EXPECT_EQ(add[i], ca[i]);
      EXPECT_EQ(sub[i], cs[i]);
      EXPECT_EQ(mul[i], cm[i]);
      EXPECT_EQ(div[i], cd[i]);
    }
  }
}

TYPED_TEST(SimdBatch, ComparisonsAndSelectMatchPerLaneFloat) {
  using B = TypeParam;
  constexpr int W = B::kWidth;
  Rng rng;
  for (int it = 0; it < kIters; ++it) {
    alignas(64) float a[W], b[W];
    for (int i = 0; i < W; ++i) {
      a[i] = rng();
      b[i] = (i % 3 == 0) ? a[i] : rng();  // exercise equality for <= and >=
    }
    if (it == 0) a[1] = std::numeric_limits<float>::quiet_NaN();  // NaN compares false
    B x = B::load(a), y = B::load(b);
    auto lt = x < y; auto le = x <= y; auto gt = x > y; auto ge = x >= y;
    B sel = select(lt, x, y);
    B sel0 = select(x > 0.0f, x, -1.0f);
    auto both = le & ge, either = lt | gt, notlt = !lt;
    for (int i = 0; i < W; ++i) {
      EXPECT_EQ(a[i] < b[i], lt[i]);
      EXPECT_EQ(a[i] <= b[i], le[i]);
      EXPECT_EQ(a[i] > b[i], gt[i]);
      EXPECT_EQ(a[i] >= b[i], ge[i]);
      EXPECT_EQ(a[i] == b[i], both[i]);
      EXPECT_EQ(a[i] < b[i] || a[i] > b[i], either[i]);
      EXPECT_EQ(!(a[i] < b[i]), notlt[i]);
      EXPECT_EQ(bits(a[i] < b[i] ? a[i] : b[i]), bits(sel[i]));
      EXPECT_EQ(bits(a[i] > 0.0f ? a[i] : -1.0f), bits(sel0[i]));
    }
    bool any_ref = false, all_ref = true;
    for (int i = 0; i < W; ++i) { any_ref |= a[i] < b[i]; all_ref &= a[i] < b[i]; }
    EXPECT_EQ(any_ref, any(lt));
    EXPECT_EQ(all_ref, all(lt));
  }
  EXPECT_TRUE(all(B(1.0f) < B(2.0f)));
  EXPECT_FALSE(any(B(1.0f) > B(2.0f)));
}

TYPED_TEST(SimdBatch, SqrtAbsMinMaxFmaMatchPerLaneStd) {
  using B = TypeParam;
  constexpr int W = B::kWidth;
  Rng rng;
  for (int it = 0; it < kIters; ++it) {
    alignas(64) float a[W], b[W], c[W];
    for (int i = 0; i < W; ++i) { a[i] = rng(); b[i] = rng(); c[i] = rng(); }
    B x = B::load(a), y = B::load(b), z = B::load(c);
    B sq = sqrt(abs(x)), ab = abs(x), mn = min(x, y), mx = max(x, y);
    B f = fma(x, y, z), fs = fma(x, y, 1.0f), mn0 = min(x, 0.0f);
    for (int i = 0; i < W; ++i) {
      EXPECT_EQ(bits(std::sqrt(std::fabs(a[i]))), bits(sq[i]));  // sqrt is correctly rounded
      EXPECT_EQ(bits(std::fabs(a[i])), bits(ab[i]));
      EXPECT_EQ(std::min(a[i], b[i]), mn[i]);
      EXPECT_EQ(std::max(a[i], b[i]), mx[i]);
      EXPECT_EQ(bits(std::fma(a[i], b[i], c[i])), bits(f[i]));   // fused on every path
      EXPECT_EQ(bits(std::fma(a[i], b[i], 1.0f)), bits(fs[i]));
      EXPECT_EQ(std::min(a[i], 0.0f), mn0[i]);
    }
  }
  B neg0 = abs(B(-0.0f));
  EXPECT_EQ(0u, bits(neg0[0]));
  EXPECT_TRUE(std::isnan(sqrt(B(-1.0f))[W - 1]));
}

// Tie/NaN rules documented in simd.h: second operand wins, like minps/maxps.
TEST(SimdScalarOverloads, MinMaxTieAndNanRuleIsSameForFloatAndBatch) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float pairs[][2] = {{0.0f, -0.0f}, {-0.0f, 0.0f}, {nan, 1.0f}, {1.0f, nan}};
  for (const auto& p : pairs) {
    EXPECT_EQ(bits(sd::min(p[0], p[1])), bits(min(Batch<8>(p[0]), Batch<8>(p[1]))[3]));
    EXPECT_EQ(bits(sd::max(p[0], p[1])), bits(max(Batch<16>(p[0]), Batch<16>(p[1]))[9]));
    EXPECT_EQ(bits(p[1]), bits(sd::min(p[0], p[1])));
  }
}

// ------------------------------------------------- generic code, S = any

template <class S> S generic_f(S x, S y) {
  using namespace cellphys::simd;
  return select(x > S(0), sqrt(x * x + y), -y);
}

// Exercises every scalar overload through unqualified lookup.
template <class S> S generic_g(S x, S y) {
  using namespace cellphys::simd;
  S m = min(abs(x), max(y, S(0.5f)));
  return fma(m, S(2), sqrt(abs(y))) + select(x <= y, x, y);
}

}  // namespace

// Same code at global scope, next to ::sqrt from <math.h>.
template <class S> S global_f(S x, S y) {
  using namespace cellphys::simd;
  return select(x > S(0), sqrt(x * x + y), -y);
}

namespace other {
// With `using namespace std;` as well: std::min/max/abs/sqrt must not clash.
template <class S> S with_std_f(S x, S y) {
  using namespace std;
  using namespace cellphys::simd;
  return select(x >= S(0), min(sqrt(abs(x)), max(x, y)), abs(y));
}
}  // namespace other

namespace {

TEST(SimdGenericCode, SameTemplateCompilesForFloatDoubleBatchAndAgreesPerLane) {
  Rng rng;
  for (int it = 0; it < kIters; ++it) {
    alignas(32) float a[8], b[8];
    for (int i = 0; i < 8; ++i) { a[i] = rng(); b[i] = std::fabs(rng()); }
    Batch<8> x = Batch<8>::load(a), y = Batch<8>::load(b);
    Batch<8> f = generic_f(x, y), g = generic_g(x, y);
    Batch<8> gl = global_f(x, y), ws = other::with_std_f(x, y);
    for (int i = 0; i < 8; ++i) {
      // f has x*x+y, which a build without -ffp-contract=off may fuse
      // differently per type: near. g and with_std_f have no contractible
      // product and every op is correctly rounded: bitwise.
      expect_rel_near(generic_f(a[i], b[i]), f[i]);
      expect_rel_near(global_f(a[i], b[i]), gl[i]);
      EXPECT_EQ(bits(generic_g(a[i], b[i])), bits(g[i]));
      EXPECT_EQ(bits(other::with_std_f(a[i], b[i])), bits(ws[i]));
      EXPECT_NEAR(generic_f(double(a[i]), double(b[i])), f[i], 1e-5 * (1.0 + std::fabs(f[i])));
      EXPECT_NEAR(generic_g(double(a[i]), double(b[i])), g[i], 1e-5 * (1.0 + std::fabs(g[i])));
      EXPECT_NEAR(other::with_std_f(double(a[i]), double(b[i])), ws[i],
                  1e-5 * (1.0 + std::fabs(ws[i])));
    }
  }
  // Batch<4> and Batch<16> instantiate too.
  EXPECT_EQ(generic_f(2.0f, 5.0f), generic_f(Batch<4>(2.0f), Batch<4>(5.0f))[3]);
  EXPECT_EQ(generic_f(-2.0f, 5.0f), generic_f(Batch<16>(-2.0f), Batch<16>(5.0f))[15]);
}

}  // namespace

TEST(Transpose, EightByEightMovesRowsToColumns) {
  alignas(32) float m[8][8];
  for (int r = 0; r < 8; ++r)
    for (int c = 0; c < 8; ++c) m[r][c] = static_cast<float>(10 * r + c);
  const float* rows[8];
  for (int r = 0; r < 8; ++r) rows[r] = m[7 - r];  // rows may come from anywhere
  alignas(32) float out[64];
  cellphys::simd::transpose8(rows, out);
  for (int r = 0; r < 8; ++r)
    for (int c = 0; c < 8; ++c) EXPECT_EQ(out[8 * c + r], m[7 - r][c]) << r << "," << c;
  cellphys::simd::vf8 columns[8];  // the same into registers
  cellphys::simd::transpose8(rows, columns);
  for (int r = 0; r < 8; ++r)
    for (int c = 0; c < 8; ++c) EXPECT_EQ(cellphys::simd::extract(columns[c], r), m[7 - r][c]) << r << "," << c;
}
