// Accuracy and stability of the integration methods of the compute kernel, measured against
// things we did not write: closed-form solutions of the ODEs (oscillators, projectile, the
// torque-free asymmetric body in Jacobi elliptic functions) and the closed-form solutions of
// the textbook discrete maps (backward, forward and symplectic Euler on a linear spring).
// Every island goes through the whole kernel (pack, DMA, validate, integrate, result), one
// island per step, rebuilt from the advanced bodies: the kernel is stateless.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <complex>
#include <string>
#include <vector>

#include "runtime/spu/kernel.h"
#include "tests/support/closed_forms.h"
#include "tests/support/island_sim.h"
#include "tests/support/record.h"

namespace {

using namespace cellphys;
using namespace cellphys::test_support;
using spu::Integrator;
using spu::IslandBuilder;
using spu::IslandStatus;
using cd = std::complex<double>;

std::string name_of(Integrator i) { return spu::integrator_name(i); }

// ---- a body on a spring to a fixed world point, moving along x -----------------------------

// The spring is a Spring_Force of rest length `rest` to the world origin (the body starts at
// x = rest + A), or, with p2p, a zero-length point_to_point joint (the body starts at x = A).
// Either way the motion stays on the x axis and the force is exactly linear in it.
struct Oscillator {
  double k = 100.0, m = 1.0, c = 0.0, A = 0.1, rest = 0.5;
  bool p2p = false;

  double omega() const { return std::sqrt(k / m); }
  double origin() const { return p2p ? 0.0 : rest; }

  void setup(Sim& s, Integrator integ, double h, float tol = 1e-5f, uint32_t solver = 0) const {
    s.settings.integrator = integ;
    s.settings.h = h;
    s.settings.tolerance = tol;
    s.settings.solver = solver;
    Rigid_Body_Fields b = make_box(m, 0.1, 0.1, 0.1);
    b.position[0] = float(origin() + A);
    s.bodies = {b};
    const float kf = float(k), cf = float(c), restf = float(rest);
    if (p2p) {
      s.forces = [kf, cf](IslandBuilder& ib) {
        gen::Point_To_Point_Constraint_Force f{};
        f.stiffness = kf, f.damping = cf, f.body_a = 0, f.body_b = -1;
        ib.add(gen::ForceType::point_to_point, f);
      };
    } else {
      s.forces = [kf, cf, restf](IslandBuilder& ib) {
        gen::Spring_Force f{};
        f.stiffness = kf, f.damping = cf, f.rest_length = restf, f.body_a = 0, f.body_b = -1;
        ib.add(gen::ForceType::spring, f);
      };
    }
  }
  double x(const Sim& s) const { return s.bodies[0].position[0] - origin(); }
  double v(const Sim& s) const { return s.bodies[0].velocity[0]; }
  /// z = x + i v / omega: the state in the plane where the exact flow is a rotation.
  cd z(const Sim& s) const { return {x(s), v(s) / omega()}; }
  cd z_exact(double t) const { return A * std::exp(cd(0.0, -omega() * t)); }
  /// Energy relative to the start: (x^2 + (v/w)^2) / A^2.
  double energy_ratio(const Sim& s) const { return std::norm(z(s)) / (A * A); }
  bool stays_on_axis(const Sim& s) const {
    const auto& b = s.bodies[0];
    return b.position[1] == 0.0f && b.position[2] == 0.0f && b.velocity[1] == 0.0f && b.velocity[2] == 0.0f;
  }
};

// ---- 1. spring-mass against the closed form, per method ------------------------------------

constexpr double kH = 1.0 / 60.0;
constexpr int kTwoPeriods = 76;  // 2 * 2 pi / 10 = 1.257 s at 60 Hz

// Largest |z - z_exact| / A over two periods.
double worst_vs_closed_form(Integrator integ, float tol, uint32_t solver, int* substeps_max = nullptr) {
  Oscillator o;
  Sim s;
  o.setup(s, integ, kH, tol, solver);
  double worst = 0.0;
  int subs = 0;
  const int done = s.run(kTwoPeriods, [&](int n) {
    worst = std::max(worst, std::abs(o.z(s) - o.z_exact((n + 1) * kH)) / o.A);
    subs = std::max<int>(subs, int(s.last.substeps));
  });
  EXPECT_EQ(done, kTwoPeriods) << name_of(integ) << ": " << spu::status_name(s.last.status);
  EXPECT_TRUE(o.stays_on_axis(s));
  if (substeps_max) *substeps_max = subs;
  return worst;
}

TEST(SpringMass, RungeKutta4MatchesClosedFormOverTwoPeriods) {
  const double worst = worst_vs_closed_form(Integrator::rk4, 1e-5f, 0);
  record("rk4_worst_rel_error", worst);
  // phase error of RK4 ~ (h w)^5 / 120 per step: 76 steps at h w = 1/6 give ~ 8e-5
  EXPECT_LT(worst, 1e-3);
}

TEST(SpringMass, RosenbrockAtTightToleranceMatchesClosedFormOverTwoPeriods) {
  int subs = 0;
  const double worst = worst_vs_closed_form(Integrator::rosenbrock, 1e-6f, 0, &subs);
  record("rosenbrock_1e-6_worst_rel_error", worst);
  record("rosenbrock_1e-6_max_substeps", subs);
  EXPECT_LT(worst, 1e-3);
  EXPECT_GT(subs, 1) << "a 1e-6 tolerance at h w = 1/6 needs substeps";
}

TEST(SpringMass, SymplecticEulerStaysNearClosedFormAndKeepsEnergyBounded) {
  const double theta = 10.0 * kH;
  Oscillator o;
  Sim s;
  o.setup(s, Integrator::symplectic_euler, kH);
  double worst = 0.0, worst_energy = 0.0;
  // symplectic Euler keeps p^2 + x^2 - theta x p exactly, so x^2 + p^2 stays within a factor
  // 1 +- theta/2 of its start; its solution is off the exact one by O(theta) A
  s.run(6 * kTwoPeriods, [&](int n) {
    if (n < kTwoPeriods) worst = std::max(worst, std::abs(o.z(s) - o.z_exact((n + 1) * kH)) / o.A);
    worst_energy = std::max(worst_energy, std::fabs(o.energy_ratio(s) - 1.0));
  });
  EXPECT_EQ(s.failures, 0);
  record("symplectic_euler_worst_rel_error", worst);
  record("symplectic_euler_worst_energy_deviation_12_periods", worst_energy);
  EXPECT_LT(worst, 0.25);
  EXPECT_LT(worst_energy, theta / (2.0 - theta) + 1e-4);
}

// The closed-form solution of a linear one-step map z_{n+1} = T z_n, T a 2x2 matrix on (x, p).
struct Map2 {
  double a, b, c, d;  // [[a, b], [c, d]]
  cd apply(cd z, int n) const {
    double x = z.real(), p = z.imag();
    for (int k = 0; k < n; ++k) {
      const double x1 = a * x + b * p, p1 = c * x + d * p;
      x = x1, p = p1;
    }
    return {x, p};
  }
};

// Backward Euler on x'' = -w^2 x is z_{n+1} = z_n / (1 + i theta): the energy shrinks by
// exactly 1 / (1 + theta^2) per step (DESIGN.md: one linearly implicit step is backward Euler).
void expect_backward_euler(Integrator integ, double amplitude = 0.1, uint32_t solver = 0) {
  SCOPED_TRACE(name_of(integ) + " A = " + sci(amplitude) + " m, solver " + std::to_string(solver));
  Oscillator o;
  o.A = amplitude;
  o.p2p = true;  // the body's position is the displacement: float resolves small amplitudes
  Sim s;
  o.setup(s, integ, kH, 1e-5f, solver);
  const double theta = o.omega() * kH;
  double worst_factor = 0.0, worst_z = 0.0;
  s.run(kTwoPeriods, [&](int n) {
    const int steps = n + 1;
    const double expect = std::pow(1.0 + theta * theta, -steps);
    worst_factor = std::max(worst_factor, std::fabs(o.energy_ratio(s) / expect - 1.0));
    const cd zd = o.A * std::pow(cd(1.0, theta), -steps);
    worst_z = std::max(worst_z, std::abs(o.z(s) - zd) / o.A);
  });
  EXPECT_EQ(s.failures, 0);
  EXPECT_TRUE(o.stays_on_axis(s));
  const std::string tag =
      name_of(integ) + (amplitude == 0.1 ? "" : "_A" + sci(amplitude, 1) + "_solver" + std::to_string(solver));
  record(tag + "_energy_factor_worst_rel_dev", worst_factor);
  record(tag + "_vs_backward_euler_worst_rel_error", worst_z);
  record(tag + "_energy_after_two_periods", o.energy_ratio(s));
  EXPECT_LT(worst_factor, 1e-3) << "energy must shrink by 1/(1+(hw)^2) per step";
  EXPECT_LT(worst_z, 1e-4);
}

TEST(SpringMass, ImplicitSplitStepIsExactlyBackwardEuler) { expect_backward_euler(Integrator::implicit_split); }
TEST(SpringMass, SeedImplicitEulerStepIsExactlyBackwardEuler) { expect_backward_euler(Integrator::implicit_euler); }
TEST(SpringMass, ImplicitStepIsBackwardEulerAtAnyAmplitude) {
  // the problem is linear, so the step must not depend on the amplitude: 10 um and 1 um too,
  // with every solver (at 60 Hz the right-hand side h W g is then ~1e-5 m/s)
  for (uint32_t solver : {2u, 0u, 1u})
    for (double A : {1e-3, 1e-5, 1e-6}) expect_backward_euler(Integrator::implicit_split, A, solver);
}

TEST(SpringMass, ExplicitEulerGainsEnergyByOnePlusHOmegaSquaredPerStep) {
  Oscillator o;
  Sim s;
  o.setup(s, Integrator::explicit_euler, kH);
  const double theta = o.omega() * kH;
  double worst_factor = 0.0, worst_z = 0.0;
  s.run(kTwoPeriods, [&](int n) {
    const int steps = n + 1;
    worst_factor = std::max(worst_factor, std::fabs(o.energy_ratio(s) / std::pow(1.0 + theta * theta, steps) - 1.0));
    worst_z = std::max(worst_z, std::abs(o.z(s) - o.A * std::pow(cd(1.0, -theta), steps)) / o.A);
  });
  EXPECT_EQ(s.failures, 0);
  record("explicit_euler_energy_after_two_periods", o.energy_ratio(s));
  EXPECT_LT(worst_factor, 1e-3);
  EXPECT_LT(worst_z, 1e-4);
}

TEST(SpringMass, SymplecticEulerFollowsItsDiscreteMapExactly) {
  Oscillator o;
  Sim s;
  o.setup(s, Integrator::symplectic_euler, kH);
  const double th = o.omega() * kH;
  // p1 = p0 - th x0, x1 = x0 + th p1
  const Map2 map{1.0 - th * th, th, -th, 1.0};
  double worst = 0.0;
  s.run(kTwoPeriods, [&](int n) { worst = std::max(worst, std::abs(o.z(s) - map.apply(o.A, n + 1)) / o.A); });
  EXPECT_EQ(s.failures, 0);
  record("symplectic_euler_vs_discrete_map_worst_rel_error", worst);
  EXPECT_LT(worst, 1e-4);
}

// ---- 2. damped oscillator ---------------------------------------------------------------------

void expect_damped(Integrator integ, float tol) {
  SCOPED_TRACE(name_of(integ));
  Oscillator o;
  const double zeta = 0.1;
  o.c = 2.0 * zeta * std::sqrt(o.k * o.m);
  Sim s;
  o.setup(s, integ, kH, tol);
  double worst = 0.0;
  const int steps = 120;  // 2 s: the amplitude falls to exp(-2) of its start
  const int done = s.run(steps, [&](int n) {
    const auto [x, v] = damped_oscillator(o.omega(), zeta, o.A, 0.0, (n + 1) * kH);
    worst = std::max(worst, std::abs(o.z(s) - cd(x, v / o.omega())) / o.A);
  });
  EXPECT_EQ(done, steps) << spu::status_name(s.last.status) << " " << s.last.error;
  record(name_of(integ) + "_damped_worst_rel_error", worst);
  EXPECT_LT(worst, 1e-3);
}

TEST(DampedOscillator, RungeKutta4MatchesUnderdampedClosedForm) { expect_damped(Integrator::rk4, 1e-5f); }
TEST(DampedOscillator, RosenbrockAtTightToleranceMatchesUnderdampedClosedForm) {
  expect_damped(Integrator::rosenbrock, 1e-6f);
}

// ---- 3. projectile ----------------------------------------------------------------------------

struct Projectile {
  double x0[3] = {0.0, 0.0, 1.0}, v0[3] = {3.0, -1.0, 5.0};
  void setup(Sim& s, Integrator integ) const {
    s.settings.integrator = integ;
    s.settings.h = kH;
    s.settings.tolerance = 1e-5f;
    Rigid_Body_Fields b = make_box(2.0, 0.1, 0.2, 0.3);
    for (int k = 0; k < 3; ++k) b.position[k] = float(x0[k]), b.velocity[k] = float(v0[k]);
    s.bodies = {b};
    s.forces = [](IslandBuilder& ib) { ib.add_global(gen::ForceType::gravity); };  // default g = (0, 0, -9.81)
  }
};

// Runs 1 s and checks x_n = x0 + v0 t + g t^2 / 2 + offset * g h t and v_n = v0 + g t.
void expect_projectile(Integrator integ, double offset) {
  SCOPED_TRACE(name_of(integ));
  const double g[3] = {0.0, 0.0, -9.81};
  Projectile p;
  Sim s;
  p.setup(s, integ);
  double worst_x = 0.0, worst_v = 0.0;
  s.run(60, [&](int n) {
    const double t = (n + 1) * kH;
    for (int k = 0; k < 3; ++k) {
      const double x = p.x0[k] + p.v0[k] * t + 0.5 * g[k] * t * t + offset * g[k] * kH * t;
      worst_x = std::max(worst_x, std::fabs(s.bodies[0].position[k] - x));
      worst_v = std::max(worst_v, std::fabs(s.bodies[0].velocity[k] - (p.v0[k] + g[k] * t)));
    }
    for (int k = 0; k < 3; ++k) EXPECT_EQ(s.bodies[0].angular_velocity[k], 0.0f);
  });
  EXPECT_EQ(s.failures, 0);
  record(name_of(integ) + "_projectile_worst_position_error_m", worst_x);
  record(name_of(integ) + "_projectile_worst_velocity_error_m_s", worst_v);
  // float state: ~1e-6 relative per step on positions of a few metres; the method's own
  // offset g h t / 2 is 0.08 m at t = 1 s, so 1e-4 m tells them apart
  EXPECT_LT(worst_x, 1e-4);
  EXPECT_LT(worst_v, 1e-4);
}

TEST(Projectile, SymplecticEulerCarriesExactlyHalfGHTOffset) { expect_projectile(Integrator::symplectic_euler, 0.5); }
TEST(Projectile, ImplicitSplitCarriesExactlyHalfGHTOffset) { expect_projectile(Integrator::implicit_split, 0.5); }
TEST(Projectile, SeedImplicitEulerCarriesExactlyHalfGHTOffset) { expect_projectile(Integrator::implicit_euler, 0.5); }
TEST(Projectile, ExplicitEulerCarriesExactlyMinusHalfGHTOffset) { expect_projectile(Integrator::explicit_euler, -0.5); }
TEST(Projectile, RungeKutta4IsExact) { expect_projectile(Integrator::rk4, 0.0); }
TEST(Projectile, RosenbrockIsExact) { expect_projectile(Integrator::rosenbrock, 0.0); }

// ---- 4. torque-free asymmetric body -------------------------------------------------------------

// Half-extents 0.05, 0.2, 0.4 m, 1 kg: I = (0.0667, 0.0542, 0.0142) kg m^2, y intermediate.
struct SpinningBox {
  std::array<double, 3> w0 = {1.0, 10.0, 1.0};  // body frame = world frame at identity
  void setup(Sim& s, Integrator integ, double h, float tol = 1e-5f) const {
    s.settings.integrator = integ;
    s.settings.h = h;
    s.settings.tolerance = tol;
    Rigid_Body_Fields b = make_box(1.0, 0.05, 0.2, 0.4);
    for (int k = 0; k < 3; ++k) b.angular_velocity[k] = float(w0[k]);
    s.bodies = {b};
    // every non-spherical body carries its gyroscopic instance; implicit_split ignores it
    s.forces = [](IslandBuilder& ib) {
      gen::Gyroscopic_Force g{};
      g.body_a = 0;
      ib.add(gen::ForceType::gyroscopic, g);
    };
  }
  std::array<double, 3> inertia(const Sim& s) const {
    const auto& b = s.bodies[0];
    return {b.inertia_body[0], b.inertia_body[1], b.inertia_body[2]};
  }
  static std::array<double, 3> body_omega(const Sim& s) {
    const auto& b = s.bodies[0];
    const Mat3d R = quat_to_matrix(quat_normalized(Quatd::load(b.orientation)));
    const Vec3d w = mul_transpose(R, Vec3d::load(b.angular_velocity));
    return {w.x, w.y, w.z};
  }
};

struct Drift {
  double L_norm = 0, L_vec = 0, energy = 0;  // final relative changes (signed for norms)
  double worst_L_vec = 0, worst_energy_up = 0;
  int failures = 0;
};

Drift spin_drift(const SpinningBox& box, Integrator integ, double h, double seconds) {
  Sim s;
  box.setup(s, integ, h);
  const Vec3d L0 = angular_momentum(s.bodies[0]);
  const double E0 = rotational_energy(s.bodies[0]);
  Drift d;
  s.run(int(std::lround(seconds / h)), [&](int) {
    const Vec3d L = angular_momentum(s.bodies[0]);
    d.worst_L_vec = std::max(d.worst_L_vec, norm(L - L0) / norm(L0));
    d.worst_energy_up = std::max(d.worst_energy_up, rotational_energy(s.bodies[0]) / E0 - 1.0);
  });
  const Vec3d L = angular_momentum(s.bodies[0]);
  d.L_norm = norm(L) / norm(L0) - 1.0;
  d.L_vec = norm(L - L0) / norm(L0);
  d.energy = rotational_energy(s.bodies[0]) / E0 - 1.0;
  d.failures = s.failures;
  return d;
}

void record_drift(const std::string& tag, const Drift& d) {
  record(tag + "_L_norm_rel_change", d.L_norm);
  record(tag + "_L_vector_rel_change", d.L_vec);
  record(tag + "_energy_rel_change", d.energy);
}

TEST(TorqueFree, ClosedFormAgreesWithDoublePrecisionEulerEquations) {
  // the Jacobi-elliptic solution against RK4 in double on Euler's equations, step 1e-5 s:
  // checks the helper (axis order, signs, phase) before it judges the kernel
  SpinningBox box;
  Sim s;
  box.setup(s, Integrator::rk4, kH);
  const auto I = box.inertia(s);
  for (const auto& w0 : {std::array<double, 3>{1, 10, 1}, std::array<double, 3>{6, -2, 1},
                         std::array<double, 3>{0.2, 1, -6}, std::array<double, 3>{-5, 0.5, 1}}) {
    const TorqueFreeBody tf(I, w0);
    std::array<double, 3> w = w0;
    auto f = [&](const std::array<double, 3>& u) {
      return std::array<double, 3>{(I[1] - I[2]) / I[0] * u[1] * u[2], (I[2] - I[0]) / I[1] * u[2] * u[0],
                                   (I[0] - I[1]) / I[2] * u[0] * u[1]};
    };
    const double h = 1e-5;
    for (int n = 1; n <= 100000; ++n) {
      std::array<double, 3> k1 = f(w), t, k2, k3, k4;
      for (int i = 0; i < 3; ++i) t[i] = w[i] + 0.5 * h * k1[i];
      k2 = f(t);
      for (int i = 0; i < 3; ++i) t[i] = w[i] + 0.5 * h * k2[i];
      k3 = f(t);
      for (int i = 0; i < 3; ++i) t[i] = w[i] + h * k3[i];
      k4 = f(t);
      for (int i = 0; i < 3; ++i) w[i] += h / 6 * (k1[i] + 2 * k2[i] + 2 * k3[i] + k4[i]);
      if (n % 25000 == 0) {
        const auto c = tf.omega(n * h);
        for (int i = 0; i < 3; ++i) EXPECT_NEAR(c[i], w[i], 1e-7 * (1 + std::fabs(w[i]))) << "t = " << n * h;
      }
    }
  }
}

TEST(TorqueFree, ImplicitSplitConservesMomentumAndEnergyOver10s) {
  const Drift d = spin_drift(SpinningBox{}, Integrator::implicit_split, kH, 10.0);
  record_drift("implicit_split", d);
  EXPECT_EQ(d.failures, 0);
  EXPECT_LT(std::fabs(d.L_norm), 1e-3);
  EXPECT_LT(d.worst_L_vec, 1e-3) << "the world angular momentum vector must not turn";
  EXPECT_LT(std::fabs(d.energy), 1e-2);
}

TEST(TorqueFree, RungeKutta4ConservesMomentumAndEnergyOver10s) {
  const Drift d = spin_drift(SpinningBox{}, Integrator::rk4, kH, 10.0);
  record_drift("rk4", d);
  EXPECT_EQ(d.failures, 0);
  EXPECT_LT(std::fabs(d.L_norm), 1e-3);
  EXPECT_LT(d.worst_L_vec, 1e-3);
  EXPECT_LT(std::fabs(d.energy), 1e-2);
}

TEST(TorqueFree, SeedImplicitEulerDoesNotGainEnergy) {
  const Drift d = spin_drift(SpinningBox{}, Integrator::implicit_euler, kH, 10.0);
  record_drift("implicit_euler", d);
  EXPECT_EQ(d.failures, 0);
  EXPECT_LE(d.energy, 1e-4) << "the reference design's step may lose energy, never gain it";
  EXPECT_LE(d.worst_energy_up, 1e-4);
}

TEST(TorqueFree, ExplicitMethodsDriftForTheRecord) {
  // not a goal, a reference point: what the game-engine methods do to the same body
  for (Integrator integ : {Integrator::symplectic_euler, Integrator::explicit_euler}) {
    const Drift d = spin_drift(SpinningBox{}, integ, kH, 10.0);
    record_drift(name_of(integ), d);
    EXPECT_GT(std::fabs(d.energy), 1e-2) << name_of(integ) << ": explicit rotation drifts; if it no longer does, "
                                            "move it to the conserving tests";
  }
}

// ---- 5. order of accuracy -------------------------------------------------------------------------

struct OrderCase {
  Integrator integ;
  double lo, hi;  // band for the error ratio when h halves
};

class SpringOrder : public ::testing::TestWithParam<OrderCase> {};

// Phase-space error |z - z_exact| / A at time T for steps h0, h0/2, h0/4.
std::array<double, 3> spring_errors(Integrator integ, const Oscillator& o, double h0, double T, float tol,
                                    uint32_t solver, bool one_substep) {
  std::array<double, 3> e{};
  for (int j = 0; j < 3; ++j) {
    const double h = h0 / (1 << j);
    const int N = int(std::lround(T / h));
    Sim s;
    o.setup(s, integ, h, tol, solver);
    int done = s.run(N, [&](int) {
      if (one_substep) {
        EXPECT_EQ(s.last.substeps, 1u) << "the controller must not split the step here";
      }
    });
    EXPECT_EQ(done, N);
    e[j] = std::abs(o.z(s) - o.z_exact(N * h)) / o.A;
  }
  return e;
}

TEST_P(SpringOrder, ErrorShrinksAtTheMethodsOrderWhenHHalves) {
  const OrderCase c = GetParam();
  Oscillator o;
  o.p2p = true;  // zero-length joint at the origin: positions near 0 keep float noise low
  o.A = 1.0;
  double h0 = 0.05, T = 2.0;
  float tol = 1e-6f;
  uint32_t solver = 0;
  bool one_substep = false;
  if (c.integ == Integrator::rk4) {
    // fourth order: large steps so the error at h0/4 (~1e-5) stays far above float noise
    o.k = 100.0, h0 = 0.08, T = 1.6;
  } else {
    o.k = 4.0;  // w = 2: explicit Euler's growth exp(h w^2 T / 2) stays near 1
  }
  if (c.integ == Integrator::rosenbrock) {
    // a tolerance so loose the controller takes one step per frame: this measures ROS2, not
    // the controller; the direct solver, because the loose tolerance also loosens CGS
    tol = 1e3f, solver = 2, one_substep = true;
  }
  const auto e = spring_errors(c.integ, o, h0, T, tol, solver, one_substep);
  const double r1 = e[0] / e[1], r2 = e[1] / e[2];
  const std::string tag = "spring_" + name_of(c.integ);
  record(tag + "_errors", sci(e[0]) + " " + sci(e[1]) + " " + sci(e[2]));
  record(tag + "_ratio_1", r1);
  record(tag + "_ratio_2", r2);
  EXPECT_GT(e[2], 1e-5) << "the smallest error must stay well above float noise";
  EXPECT_GE(r1, c.lo);
  EXPECT_LE(r1, c.hi);
  EXPECT_GE(r2, c.lo);
  EXPECT_LE(r2, c.hi);
}

INSTANTIATE_TEST_SUITE_P(Integrators, SpringOrder,
                         ::testing::Values(OrderCase{Integrator::explicit_euler, 1.7, 2.4},
                                           OrderCase{Integrator::symplectic_euler, 1.7, 2.4},
                                           OrderCase{Integrator::implicit_euler, 1.7, 2.4},
                                           OrderCase{Integrator::implicit_split, 1.7, 2.4},
                                           OrderCase{Integrator::rosenbrock, 3.3, 4.8},
                                           OrderCase{Integrator::rk4, 12.0, 20.0}),
                         [](const ::testing::TestParamInfo<OrderCase>& i) { return name_of(i.param.integ); });

class RotationOrder : public ::testing::TestWithParam<OrderCase> {};

TEST_P(RotationOrder, BodyRateErrorShrinksAtTheMethodsOrderWhenHHalves) {
  // torque-free body away from the separatrix, 0.8 s: body-frame rate vs the elliptic closed form
  const OrderCase c = GetParam();
  SpinningBox box;
  box.w0 = {6.0, -2.0, 1.0};
  const double T = 0.8, h0 = 1.0 / 15.0;
  std::array<double, 3> e{};
  for (int j = 0; j < 3; ++j) {
    const double h = h0 / (1 << j);
    const int N = int(std::lround(T / h));
    Sim s;
    box.setup(s, c.integ, h);
    EXPECT_EQ(s.run(N), N);
    const TorqueFreeBody tf(box.inertia(s), box.w0);
    const auto we = tf.omega(N * h), w = SpinningBox::body_omega(s);
    e[j] = std::hypot(w[0] - we[0], w[1] - we[1], w[2] - we[2]);
  }
  const double r1 = e[0] / e[1], r2 = e[1] / e[2];
  const std::string tag = "rotation_" + name_of(c.integ);
  record(tag + "_errors_rad_s", sci(e[0]) + " " + sci(e[1]) + " " + sci(e[2]));
  record(tag + "_ratio_1", r1);
  record(tag + "_ratio_2", r2);
  EXPECT_GT(e[2], 2e-5) << "the smallest error must stay well above float noise";
  EXPECT_GE(r1, c.lo);
  EXPECT_LE(r1, c.hi);
  EXPECT_GE(r2, c.lo);
  EXPECT_LE(r2, c.hi);
}

// implicit_split's rotation is the implicit midpoint rule: second order, unlike its force part
INSTANTIATE_TEST_SUITE_P(Integrators, RotationOrder,
                         ::testing::Values(OrderCase{Integrator::implicit_split, 3.3, 4.8},
                                           OrderCase{Integrator::rk4, 12.0, 20.0}),
                         [](const ::testing::TestParamInfo<OrderCase>& i) { return name_of(i.param.integ); });

// ---- 6. stability where methods fail ---------------------------------------------------------------

TEST(Stability, StiffSpringImplicitStaysBoundedWhereExplicitEulerDiverges) {
  // k = 1e6 N/m, m = 1 kg: w = 1000 rad/s, h w = 16.7, far past explicit Euler's limit
  Oscillator o;
  o.k = 1e6;
  const int steps = 120;  // 2 s
  for (Integrator integ : {Integrator::implicit_split, Integrator::implicit_euler}) {
    Sim s;
    o.setup(s, integ, kH);
    double worst = 0.0;
    const int done = s.run(steps, [&](int) { worst = std::max(worst, std::fabs(o.x(s))); });
    EXPECT_EQ(done, steps) << name_of(integ);
    EXPECT_LE(worst, o.A * (1 + 1e-6)) << name_of(integ) << ": |x| exceeded the initial amplitude";
    record("stiff_" + name_of(integ) + "_max_abs_x_over_A", worst / o.A);
  }
  Sim s;
  o.setup(s, Integrator::explicit_euler, kH);
  double growth = 0.0;
  const int done = s.run(steps, [&](int) { growth = std::max(growth, std::fabs(o.x(s)) / o.A); });
  record("stiff_explicit_euler_growth", growth);
  record("stiff_explicit_euler_steps_before_failure", done);
  EXPECT_TRUE(growth > 1e3 || s.last.status == IslandStatus::failed)
      << "explicit Euler should diverge: growth " << growth << ", status " << spu::status_name(s.last.status);
}

TEST(Stability, HeavyChainOfJointsHangsBoundedWithImplicitSplit) {
  // 20 links of 0.2 m hanging from a world point by point_to_point joints; the last link is
  // 1000x heavier than the others; released at 30 degrees from the vertical under gravity
  constexpr int kLinks = 20;
  constexpr double kStiffness = 1e6, kDamping = 1e3, kHalf = 0.1;
  const double angle = M_PI / 6, dir[3] = {std::sin(angle), 0.0, -std::cos(angle)};
  Sim s;
  s.settings.integrator = Integrator::implicit_split;
  s.settings.h = kH;
  s.settings.tolerance = 1e-4f;
  // a link's long axis is body z; turning it by -30 degrees about y sends +z to -dir, so each
  // link's top (+z) points back up the chain
  const Quatd q = quat_exp(Vec3d{0.0, -angle, 0.0});
  for (int i = 0; i < kLinks; ++i) {
    const double m = i == kLinks - 1 ? 1000.0 : 1.0;
    Rigid_Body_Fields b = make_box(m, 0.02, 0.02, kHalf);
    const double along = (2 * i + 1) * kHalf;
    for (int k = 0; k < 3; ++k) b.position[k] = float(along * dir[k]);
    b.orientation[0] = float(q.w), b.orientation[1] = float(q.x), b.orientation[2] = float(q.y),
    b.orientation[3] = float(q.z);
    s.bodies.push_back(b);
  }
  // check the set-up: each link's top point is the previous link's bottom point
  const float top[3] = {0, 0, float(kHalf)}, bottom[3] = {0, 0, float(-kHalf)};
  ASSERT_LT(norm(world_point(s.bodies[0], top)), 1e-6);
  for (int i = 1; i < kLinks; ++i)
    ASSERT_LT(norm(world_point(s.bodies[i], top) - world_point(s.bodies[i - 1], bottom)), 1e-6);
  s.forces = [&](IslandBuilder& ib) {
    for (int i = 0; i < kLinks; ++i) {
      gen::Point_To_Point_Constraint_Force j{};
      j.point_a[2] = float(kHalf);  // top of link i
      j.stiffness = float(kStiffness), j.damping = float(kDamping);
      j.body_a = i;
      if (i == 0) {
        j.body_b = -1;  // the world point (0, 0, 0)
      } else {
        j.point_b[2] = float(-kHalf);  // bottom of link i - 1
        j.body_b = i - 1;
      }
      ib.add(gen::ForceType::point_to_point, j);
    }
    ib.add_global(gen::ForceType::gravity);
  };
  // the static stretch of the top joint: (19 + 1000) kg * 9.81 / 1e6 = 1 cm
  const double static_stretch = (kLinks - 1 + 1000.0) * 9.81 / kStiffness;
  double worst_stretch = 0.0, worst_speed = 0.0;
  uint32_t worst_halvings = 0;
  const int steps = 180;  // 3 s
  const int done = s.run(steps, [&](int) {
    worst_halvings = std::max(worst_halvings, s.last.halvings);
    for (int i = 0; i < kLinks; ++i) {
      ASSERT_TRUE(finite_body(s.bodies[i]));
      const Vec3d a = world_point(s.bodies[i], top);
      const Vec3d b = i == 0 ? Vec3d{0, 0, 0} : world_point(s.bodies[i - 1], bottom);
      worst_stretch = std::max(worst_stretch, norm(a - b));
      worst_speed = std::max(worst_speed, norm(Vec3d::load(s.bodies[i].velocity)));
    }
  });
  EXPECT_EQ(done, steps) << spu::status_name(s.last.status);
  record("chain_worst_joint_stretch_m", worst_stretch);
  record("chain_static_stretch_m", static_stretch);
  record("chain_worst_link_speed_m_s", worst_speed);
  record("chain_solver_iterations_last_step", s.last.solver_iterations);
  record("chain_max_halvings", worst_halvings);
  // sane: a joint never opens beyond 5 times the static stretch of the top one, and nothing
  // moves faster than a 4 m pendulum released at 30 degrees can (sqrt(2 g 4 (1 - cos 30)) = 3.3 m/s) by much
  EXPECT_LT(worst_stretch, 5 * static_stretch);
  EXPECT_LT(worst_speed, 10.0);
  // and the heavy end hangs below the anchor, within the chain's length
  const double end_z = s.bodies[kLinks - 1].position[2];
  EXPECT_LT(end_z, 0.0);
  EXPECT_GT(end_z, -2 * kLinks * kHalf - 0.5);
}

TEST(Stability, IntermediateAxisSpinAt20RadPerSecond) {
  // the Dzhanibekov flip at h w = 1/3: the reference design's step must not gain energy, the split one
  // must keep it (and the momentum vector)
  SpinningBox box;
  box.w0 = {0.2, 20.0, 0.2};
  const Drift seed = spin_drift(box, Integrator::implicit_euler, kH, 10.0);
  record_drift("spin20_implicit_euler", seed);
  EXPECT_EQ(seed.failures, 0);
  EXPECT_LE(seed.worst_energy_up, 1e-4) << "implicit_euler gained energy";
  const Drift split = spin_drift(box, Integrator::implicit_split, kH, 10.0);
  record_drift("spin20_implicit_split", split);
  EXPECT_EQ(split.failures, 0);
  EXPECT_LT(std::fabs(split.energy), 1e-3);
  EXPECT_LT(std::fabs(split.L_norm), 1e-3);
  EXPECT_LT(split.worst_L_vec, 1e-3);
}

// ---- 7. Rosenbrock follows the requested accuracy ------------------------------------------------------

TEST(Rosenbrock, TighterToleranceTakesMoreSubstepsAndErrsLess) {
  Oscillator o;
  int prev_substeps = 0;
  double prev_error = 1e9;
  for (float tol : {1e-2f, 1e-4f, 1e-6f}) {
    Sim s;
    o.setup(s, Integrator::rosenbrock, kH, tol);
    int substeps = 0;
    double worst = 0.0;
    const int done = s.run(kTwoPeriods, [&](int n) {
      substeps += int(s.last.substeps);
      worst = std::max(worst, std::abs(o.z(s) - o.z_exact((n + 1) * kH)) / o.A);
    });
    const std::string tag = "rosenbrock_tol_" + sci(tol, 1);
    EXPECT_EQ(done, kTwoPeriods) << tag << ": " << spu::status_name(s.last.status);
    record(tag + "_substeps", substeps);
    record(tag + "_worst_rel_error", worst);
    EXPECT_GT(substeps, prev_substeps) << tag;
    EXPECT_LT(worst, prev_error) << tag;
    prev_substeps = substeps, prev_error = worst;
  }
}

TEST(Rosenbrock, TightToleranceWithTheDirectSolverCompletesEveryStep) {
  // the controller on its own: with the direct solve, tolerance 1e-6 covers every frame
  Oscillator o;
  Sim s;
  o.setup(s, Integrator::rosenbrock, kH, 1e-6f, 2);
  double worst = 0.0;
  const int done = s.run(kTwoPeriods, [&](int n) {
    worst = std::max(worst, std::abs(o.z(s) - o.z_exact((n + 1) * kH)) / o.A);
  });
  EXPECT_EQ(done, kTwoPeriods);
  EXPECT_LT(worst, 1e-3);
  record("rosenbrock_direct_1e-6_worst_rel_error", worst);
  SpinningBox box;
  box.w0 = {3.0, -1.0, 0.5};
  Sim spin;
  box.setup(spin, Integrator::rosenbrock, 1.0 / 120.0, 1e-6f);
  spin.settings.solver = 2;
  EXPECT_EQ(spin.run(60), 60);
}

TEST(Rosenbrock, TightToleranceOnASpinningBodyCompletesEveryStep) {
  // a body spinning at ~6 rad/s with its gyroscopic torque, tolerance 1e-6 (the one the
  // oscillator tests use): the controller must cover each frame, however it substeps
  SpinningBox box;
  box.w0 = {3.0, -1.0, 0.5};
  Sim s;
  box.setup(s, Integrator::rosenbrock, 1.0 / 120.0, 1e-6f);
  const int done = s.run(60);
  record("spinning_rosenbrock_1e-6_steps_done", done);
  EXPECT_EQ(done, 60) << "step " << done << " failed: halvings " << s.last.halvings << ", rejected "
                      << s.last.rejected << ", substeps " << s.last.substeps << ", solver code "
                      << s.last.solver_code;
}

}  // namespace
