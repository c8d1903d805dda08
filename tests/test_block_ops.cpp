// Generated block operations against Eigen on random data.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cstring>
#include <limits>
#include <random>
#include <vector>

#include "cellphys/gen/block_ops.h"

using namespace cellphys::gen;
using Mat6 = Eigen::Matrix<float, 6, 6>;
using Vec6 = Eigen::Matrix<float, 6, 1>;

namespace {

struct alignas(32) Block {
  float m[kBlockFloats];
};
struct alignas(32) Vec8 {
  float v[kVecFloats];
};

Block to_block(const Mat6& A) {
  Block b{};
  for (int c = 0; c < 6; ++c)
    for (int r = 0; r < 6; ++r) b.m[8 * c + padded(r)] = A(r, c);
  return b;
}
Mat6 from_block(const Block& b) {
  Mat6 A;
  for (int c = 0; c < 6; ++c)
    for (int r = 0; r < 6; ++r) A(r, c) = b.m[8 * c + padded(r)];
  return A;
}
Vec8 to_vec(const Vec6& x) {
  Vec8 v{};
  for (int r = 0; r < 6; ++r) v.v[padded(r)] = x(r);
  return v;
}
Vec6 from_vec(const Vec8& v) {
  Vec6 x;
  for (int r = 0; r < 6; ++r) x(r) = v.v[padded(r)];
  return x;
}
void expect_padding_zero(const Block& b) {
  for (int c = 0; c < 6; ++c) {
    EXPECT_EQ(b.m[8 * c + 3], 0.0f);
    EXPECT_EQ(b.m[8 * c + 7], 0.0f);
  }
}

template <class A, class B>
float rel_err(const A& a, const B& b) {
  return (a - b).norm() / (1e-30f + b.norm());
}

}  // namespace

class BlockOps : public ::testing::Test {
 protected:
  std::mt19937 rng{42};
  Mat6 random_mat() {
    std::uniform_real_distribution<float> u(-1.0f, 1.0f);
    return Mat6::NullaryExpr([&]() { return u(rng); });
  }
  Vec6 random_vec() {
    std::uniform_real_distribution<float> u(-1.0f, 1.0f);
    return Vec6::NullaryExpr([&]() { return u(rng); });
  }
};

TEST_F(BlockOps, MulAddAgreesWithEigen) {
  for (int t = 0; t < 200; ++t) {
    const Mat6 A = random_mat();
    const Vec6 x = random_vec(), y0 = random_vec();
    Block b = to_block(A);
    Vec8 xv = to_vec(x), yv = to_vec(y0);
    block_mul_add(b.m, xv.v, yv.v);
    EXPECT_LT(rel_err(from_vec(yv), y0 + A * x), 1e-6f);
    EXPECT_EQ(yv.v[3], 0.0f);
    EXPECT_EQ(yv.v[7], 0.0f);
    Vec8 z{};
    block_mul(b.m, xv.v, z.v);
    EXPECT_LT(rel_err(from_vec(z), A * x), 1e-6f);
  }
}

TEST_F(BlockOps, AxpyAndDenseAddAgreeWithEigen) {
  const Mat6 X = random_mat(), Y = random_mat();
  Block xb = to_block(X), yb = to_block(Y);
  block_axpy(0.37f, xb.m, yb.m);
  EXPECT_LT(rel_err(from_block(yb), Y + 0.37f * X), 1e-6f);
  expect_padding_zero(yb);
  Block zb = to_block(Y);
  block_add_dense(-2.5f, X.data(), zb.m);  // Eigen's storage is column-major like the kernels' output
  EXPECT_LT(rel_err(from_block(zb), Y - 2.5f * X), 1e-6f);
  expect_padding_zero(zb);
}

TEST_F(BlockOps, WTimesBlockAndIdentityLessItAgreeWithEigen) {
  for (int t = 0; t < 50; ++t) {
    const float w_lin = 0.5f + 0.1f * t;
    const Mat6 R3 = random_mat();
    const Eigen::Matrix3f Iinv = R3.topLeftCorner<3, 3>() * R3.topLeftCorner<3, 3>().transpose();
    alignas(16) float w_rot[12] = {};
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) w_rot[4 * r + c] = Iinv(r, c);
    Mat6 W = Mat6::Zero();
    W.topLeftCorner<3, 3>() = w_lin * Eigen::Matrix3f::Identity();
    W.bottomRightCorner<3, 3>() = Iinv;
    const Mat6 K = random_mat();
    Block kb = to_block(K), out = to_block(K);
    identity_minus_w_mul(w_lin, w_rot, out.m);
    EXPECT_LT(rel_err(from_block(out), Mat6::Identity() - W * K), 1e-6f);
    expect_padding_zero(out);
    Block wb{};
    block_from_w(w_lin, w_rot, wb.m);
    EXPECT_LT(rel_err(from_block(wb), W), 1e-7f);
    Block prod{};
    block_mul_block(wb.m, kb.m, prod.m);
    EXPECT_LT(rel_err(from_block(prod), W * K), 1e-6f);
  }
}

TEST_F(BlockOps, DenseMulAddAgreesWithEigen) {
  const Mat6 K = random_mat();
  const Vec6 x = random_vec(), y0 = random_vec();
  Vec8 xv = to_vec(x), yv = to_vec(y0);
  dense_mul_add(0.25f, K.data(), xv.v, yv.v);
  EXPECT_LT(rel_err(from_vec(yv), y0 + 0.25f * K * x), 1e-6f);
}

TEST_F(BlockOps, JacobiInverseAgreesWithEigenOnDiagonalBlocksOfA) {
  // Blocks shaped like A's diagonal: I + s K K^T plus a non-symmetric part, s from 1 to 1e4.
  // A float inverse cannot beat the conditioning: the bound is a small multiple of
  // kappa(A) * float epsilon against a double-precision reference. Measured: the no-pivot
  // Schur inverse is up to ~30x less accurate than Eigen's pivoting float LU on the worst
  // of these blocks (still ~1e-5 relative), which a preconditioner does not notice.
  for (int t = 0; t < 200; ++t) {
    const float scale = std::pow(10.0f, static_cast<float>(t % 5));
    const Mat6 K = random_mat();
    const Mat6 A = Mat6::Identity() + scale * (K * K.transpose()) + 0.1f * random_mat();
    Block ab = to_block(A), inv{};
    ASSERT_TRUE(block_jacobi_inverse(ab.m, inv.m));
    const Eigen::Matrix<double, 6, 6> Ad = A.cast<double>();
    const Eigen::Matrix<double, 6, 6> ref = Ad.inverse();
    const double kappa = Ad.norm() * ref.norm();
    const double ours = (from_block(inv).cast<double>() - ref).norm() / ref.norm();
    const double eps = std::numeric_limits<float>::epsilon();
    EXPECT_LT(ours, 10.0 * kappa * eps) << "t=" << t << " kappa=" << kappa;
    expect_padding_zero(inv);
  }
}

TEST_F(BlockOps, JacobiInverseEightAtOnceGivesEachBlockItsOwnBitsAndLeavesRefusedOnesAlone) {
  // Lanes in place (Ainv[l] == A[l]) and into other blocks; among them a singular block, one
  // with a NaN, one with an infinite entry, one whose determinant overflows and, last, idle
  // lanes repeating a block.
  for (int t = 0; t < 40; ++t) {
    const int lanes = 1 + t % 8;
    std::vector<Block> in(8), out(8, Block{}), alone(8, Block{});
    std::vector<bool> expected(8);
    for (int l = 0; l < 8; ++l) {
      const Mat6 K = random_mat();
      Mat6 A = Mat6::Identity() + std::pow(10.0f, float((t + l) % 5)) * (K * K.transpose()) + 0.1f * random_mat();
      if ((t + l) % 7 == 3) A.topLeftCorner<3, 3>().setZero();
      if ((t + l) % 11 == 5) A(4, 4) = std::numeric_limits<float>::quiet_NaN();
      if ((t + l) % 13 == 6) A(1, 2) = std::numeric_limits<float>::infinity();
      if ((t + l) % 17 == 8)  // its rotational 3x3 determinant overflows to +inf, not NaN
        A.bottomRightCorner<3, 3>() += 1e13f * Eigen::Matrix3f::Identity();
      in[l] = to_block(A);
      expected[l] = block_jacobi_inverse(in[l].m, alone[l].m);
    }
    const bool in_place = t % 2 == 0;
    std::vector<Block> before = in;
    const float* a[8];
    float* o[8];
    for (int l = 0; l < 8; ++l) {
      const int k = std::min(l, lanes - 1);
      a[l] = in[k].m;
      o[l] = in_place ? in[k].m : out[k].m;
    }
    const unsigned done = block_jacobi_inverse8(a, o);
    for (int l = 0; l < lanes; ++l) {
      ASSERT_EQ(bool(done >> l & 1u), bool(expected[l])) << "t=" << t << " lane " << l;
      const Block& got = in_place ? in[l] : out[l];
      const Block& want = expected[l] ? alone[l] : (in_place ? before[l] : Block{});
      EXPECT_EQ(0, std::memcmp(got.m, want.m, sizeof got.m)) << "t=" << t << " lane " << l;
    }
  }
}

TEST_F(BlockOps, JacobiInverseReportsASingularBlock) {
  Mat6 A = Mat6::Identity();
  A.topLeftCorner<3, 3>().setZero();  // singular translational part
  Block ab = to_block(A), inv{};
  EXPECT_FALSE(block_jacobi_inverse(ab.m, inv.m));
}
