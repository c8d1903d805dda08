// The free rotation of the default integrator, one body at a time and eight in SIMD lanes:
// each lane has the bits of the body alone, whatever the others in its group do.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <random>
#include <vector>

#include "runtime/spu/rigid_motion.h"

namespace {

using namespace cellphys;
using gen::Rigid_Body;

uint64_t bits(double x) {
  uint64_t u;
  std::memcpy(&u, &x, sizeof u);
  return u;
}

// A body of a kind the lanes must keep apart: a ball (isotropic: no iteration), a brick, a
// thin rod or a plate (anisotropic, turned any way, with products of inertia), spun slowly,
// fast (many fixed-point iterations) or so fast that the fixed point does not converge.
Rigid_Body random_body(std::mt19937& rng, int kind) {
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  Rigid_Body b{};
  double q[4] = {u(rng), u(rng), u(rng), u(rng)};
  const double n = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
  for (int k = 0; k < 4; ++k) b.orientation[k] = float(q[k] / n);
  float I[3] = {1.0f, 1.0f, 1.0f};
  float off = 0.0f;
  switch (kind % 4) {
    case 0: break;                                                             // ball
    case 1: I[0] = 0.4f, I[1] = 1.3f, I[2] = 1.7f, off = 0.05f; break;          // brick
    case 2: I[0] = 0.01f, I[1] = 2.0f, I[2] = 2.0f; break;                      // rod
    case 3: I[0] = 1.0f, I[1] = 1.0f, I[2] = 2.0f, off = -0.1f; break;          // plate
  }
  const float s = 0.5f + 2.0f * (u(rng) + 1.0f);
  const float inertia[6] = {I[0] * s, I[1] * s, I[2] * s, off * s, 0.0f, off == 0.0f ? 0.0f : 0.5f * off * s};
  std::memcpy(b.inertia_body, inertia, sizeof inertia);
  // the inverse of the symmetric matrix, in double, stored as the engine stores it
  const double a = inertia[0], d = inertia[1], f = inertia[2], bb = inertia[3], c = inertia[4], e = inertia[5];
  const double A = d * f - e * e, B = -(bb * f - c * e), C = bb * e - c * d;
  const double D = a * f - c * c, E = -(a * e - bb * c), F = a * d - bb * bb;
  const double det = a * A + bb * B + c * C;
  const float inv[6] = {float(A / det), float(D / det), float(F / det), float(B / det), float(C / det), float(E / det)};
  std::memcpy(b.inverse_inertia_body, inv, sizeof inv);
  const float spin = kind / 4 == 0 ? 0.5f : (kind / 4 == 1 ? 30.0f : 4000.0f);
  for (int k = 0; k < 3; ++k) b.angular_velocity[k] = spin * u(rng);
  return b;
}

struct Turn {
  bool ok;
  Quatd q1;
  Vec3d w1;
};

// The one-body free rotation as the integrator committed it before the lanes, kept here word for
// word as the reference the lanes must reproduce bit for bit.
bool reference_free_rotation(const Quatd& q0, const Mat3d& R0, const Vec3d& L, const float* inverse_inertia_body,
                             double h, Quatd* q1, Vec3d* omega1) {
  const Mat3d Iinv = symmetric<double>(inverse_inertia_body);
  const Vec3d Lb = mul_transpose(R0, L);
  Vec3d w = mul(Iinv, Lb), Lb1 = Lb;
  const float* s = inverse_inertia_body;
  bool converged = s[0] == s[1] && s[1] == s[2] && s[3] == 0.0f && s[4] == 0.0f && s[5] == 0.0f;
  const double scale = norm(Lb) + 1e-300;
  for (int it = 0; it < 60 && !converged; ++it) {
    const Vec3d a = w * (-0.5 * h);
    const Vec3d next = mul(quat_to_matrix(quat_normalized(Quatd{1.0, a.x, a.y, a.z})), Lb);
    const double d = norm(next - Lb1);
    Lb1 = next;
    w = mul(Iinv, (Lb + Lb1) * 0.5);
    converged = d <= 1e-12 * scale;
  }
  if (!converged) return false;
  const Vec3d a = w * (0.5 * h);
  *q1 = quat_normalized(quat_mul(q0, quat_normalized(Quatd{1.0, a.x, a.y, a.z})));
  const Vec3d wb = mul(Iinv, Lb1);
  *omega1 = mul(quat_to_matrix(*q1), wb);
  return std::isfinite(omega1->x) && std::isfinite(omega1->y) && std::isfinite(omega1->z);
}

// What the integrator did for one body before the lanes: the same calls, one body.
Turn alone(const Rigid_Body& b, const Vec3d& w_kick, double h) {
  const Quatd q0 = spu::orientation(b);
  const Mat3d R0 = quat_to_matrix(q0);
  const Vec3d L = mul(rotate_sym(R0, b.inertia_body), w_kick);
  Turn t{};
  t.ok = reference_free_rotation(q0, R0, L, b.inverse_inertia_body, h, &t.q1, &t.w1);
  Turn now{};  // and the one-body entry point the integrator keeps
  now.ok = spu::free_rotation(q0, R0, L, b.inverse_inertia_body, h, &now.q1, &now.w1);
  EXPECT_EQ(now.ok, t.ok);
  if (now.ok && t.ok) {
    const double a[7] = {now.q1.w, now.q1.x, now.q1.y, now.q1.z, now.w1.x, now.w1.y, now.w1.z};
    const double b7[7] = {t.q1.w, t.q1.x, t.q1.y, t.q1.z, t.w1.x, t.w1.y, t.w1.z};
    for (int k = 0; k < 7; ++k) EXPECT_EQ(bits(a[k]), bits(b7[k]));
  }
  return t;
}

TEST(WorldInertia, BodiesInLanesGetTheBitsEachGetsAlone) {
  std::mt19937 rng(11);
  for (int n : {1, 3, 8, 9, 17, 32}) {
    std::vector<Rigid_Body> bodies;
    for (int i = 0; i < n; ++i) {
      Rigid_Body b = random_body(rng, int(rng() % 4));
      b.inverse_mass = 0.1f + float(rng() % 100);
      if (i % 5 == 4) b.inverse_inertia_body[0] = 0.0f, b.inverse_mass = 0.0f;  // pinned axes give zeros
      bodies.push_back(b);
    }
    // both filled with the same junk first: every field must be written, to the same bits
    std::vector<gen::W_Element> lanes(static_cast<size_t>(n) + 1), alone(static_cast<size_t>(n));
    std::memset(static_cast<void*>(lanes.data()), 0x5a, lanes.size() * sizeof lanes[0]);
    std::memset(static_cast<void*>(alone.data()), 0x5a, alone.size() * sizeof alone[0]);
    spu::compute_ws(bodies.data(), n, lanes.data());
    for (int i = 0; i < n; ++i) {
      spu::compute_w(bodies[size_t(i)], alone[size_t(i)]);
      EXPECT_EQ(std::memcmp(&lanes[size_t(i)], &alone[size_t(i)], sizeof alone[0]), 0) << "n " << n << ", body " << i;
    }
    const unsigned char* past = reinterpret_cast<const unsigned char*>(&lanes[size_t(n)]);
    EXPECT_TRUE(std::all_of(past, past + sizeof lanes[0], [](unsigned char c) { return c == 0x5a; })) << "wrote past body " << n - 1;
  }
}

TEST(FreeRotation, EightInLanesGiveEachBodyItsOwnBitsWhateverItsNeighbours) {
  std::mt19937 rng(7);
  const double h = 1.0 / 60.0;
  int compared = 0, failed_finite = 0, failed_nan = 0, iterating = 0, isotropic = 0;
  for (int group = 0; group < 120; ++group) {
    const int count = 1 + group % 8;
    std::vector<Rigid_Body> bodies(count);
    std::vector<Vec3d> kick(count);
    std::vector<const Rigid_Body*> ptr(count);
    for (int l = 0; l < count; ++l) {
      // mostly slow and fast bodies; every seventh group ends with a brick, rod or plate spun
      // too fast for the fixed point to converge
      const bool too_fast = group % 7 == 0 && l == count - 1;
      bodies[l] = too_fast ? random_body(rng, 8 + 1 + int(rng() % 3)) : random_body(rng, 4 * int(rng() % 2) + int(rng() % 4));
      if (group % 11 == 3 && l == 0) bodies[l].angular_velocity[1] = std::numeric_limits<float>::quiet_NaN();
      kick[l] = Vec3d::load(bodies[l].angular_velocity) + Vec3d{0.01 * l, -0.02, 0.03};
      ptr[l] = &bodies[l];
    }
    Quatd q1[8];
    Vec3d w1[8];
    bool ok[8];
    spu::kicked_free_rotations(ptr.data(), kick.data(), count, h, q1, w1, ok);
    for (int l = 0; l < count; ++l) {
      const Turn t = alone(bodies[l], kick[l], h);
      ASSERT_EQ(ok[l], t.ok) << "group " << group << " lane " << l;
      ++compared;
      if (!t.ok) {
        ++(std::isfinite(kick[l].y) ? failed_finite : failed_nan);
        continue;
      }
      const float* s = bodies[l].inverse_inertia_body;
      if (s[0] == s[1] && s[1] == s[2] && s[3] == 0 && s[4] == 0 && s[5] == 0) ++isotropic;
      else ++iterating;
      const double got[7] = {q1[l].w, q1[l].x, q1[l].y, q1[l].z, w1[l].x, w1[l].y, w1[l].z};
      const double want[7] = {t.q1.w, t.q1.x, t.q1.y, t.q1.z, t.w1.x, t.w1.y, t.w1.z};
      for (int k = 0; k < 7; ++k) ASSERT_EQ(bits(got[k]), bits(want[k])) << "group " << group << " lane " << l << " value " << k;
    }
  }
  // the groups held each kind: bodies that do not iterate, that do, and that fail
  EXPECT_EQ(compared, 120 / 8 * 36);
  EXPECT_GT(isotropic, 50);
  EXPECT_GT(iterating, 200);
  EXPECT_GE(failed_finite, 120 / 7);
  EXPECT_GE(failed_nan, 120 / 11);
}

TEST(FreeRotation, EachStepKeepsTheWorldMomentumAndTheEnergyOfTumblingBricks) {
  // Torque-free bricks spun near their unstable middle axis tumble. Over a step the world
  // angular momentum L = R I R^T w is unchanged and so is the energy w.L / 2: the body-frame
  // momentum turns by one Cayley rotation and the orientation by its inverse, so both hold,
  // lane by lane, to what the stored state allows: inertias of powers of two (their inverses
  // exact in float) keep I I^-1 = 1, and the fixed point converges to 1e-12, but the
  // orientation a step starts from is a float quaternion, unit to ~1e-7, and its matrix
  // orthogonal only to that (in doubles throughout, both hold to 1e-12). A rotation the wrong
  // way, or a fixed point stopped early, is off by ~h |w| = 0.1.
  const double h = 1.0 / 60.0;
  Rigid_Body b[8] = {};
  Vec3d w[8];
  const Rigid_Body* ptr[8];
  for (int l = 0; l < 8; ++l) {
    const float s = float(1 << (l % 4));
    const float inertia[6] = {0.5f * s, 1.0f * s, 2.0f * s, 0, 0, 0}, inverse[6] = {2.0f / s, 1.0f / s, 0.5f / s, 0, 0, 0};
    std::memcpy(b[l].inertia_body, inertia, sizeof inertia);
    std::memcpy(b[l].inverse_inertia_body, inverse, sizeof inverse);
    b[l].orientation[0] = 1.0f;
    w[l] = {0.05 * (l + 1), 2.0 + l, -0.03 * l};
    ptr[l] = &b[l];
  }
  auto momentum = [](const Rigid_Body& x, const Quatd& q, const Vec3d& v) {
    return mul(rotate_sym(quat_to_matrix(q), x.inertia_body), v);
  };
  double worst_L = 0, worst_E = 0, turned = 0;
  for (int step = 0; step < 600; ++step) {  // 10 s: several tumbles each
    Quatd q1[8];
    Vec3d w1[8];
    bool ok[8];
    spu::kicked_free_rotations(ptr, w, 8, h, q1, w1, ok);
    for (int l = 0; l < 8; ++l) {
      ASSERT_TRUE(ok[l]) << "step " << step << " lane " << l;
      const Quatd q0 = spu::orientation(b[l]);
      const Vec3d L0 = momentum(b[l], q0, w[l]), L1 = momentum(b[l], q1[l], w1[l]);
      worst_L = std::max(worst_L, norm(L1 - L0) / norm(L0));
      worst_E = std::max(worst_E, std::abs(dot(w1[l], L1) - dot(w[l], L0)) / dot(w[l], L0));
      turned = std::max(turned, std::abs(q1[l].w - q0.w));
      spu::set_orientation(b[l], q1[l]);
      w[l] = {double(float(w1[l].x)), double(float(w1[l].y)), double(float(w1[l].z))};
    }
  }
  EXPECT_GT(turned, 1e-3);  // it did turn
  EXPECT_LT(worst_L, 1e-6);
  EXPECT_LT(worst_E, 1e-6);
}

}  // namespace
