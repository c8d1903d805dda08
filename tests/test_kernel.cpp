// The compute kernel's contract: solvers that agree with the direct oracle, halving on
// failure with the state untouched, the reference design's local-store budget, refusal of islands that
// do not fit or are malformed, the emulated DMA and local-store rules, and determinism.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "cellphys/gen/block_ops.h"
#include "runtime/spu/assembly.h"
#include "runtime/spu/dma.h"
#include "runtime/spu/island_image.h"
#include "runtime/spu/kernel.h"
#include "runtime/spu/local_store.h"
#include "testing/reference_island.h"
#include "tests/support/backward_sharer.h"
#include "tests/support/island_sim.h"
#include "tests/support/record.h"

namespace {

using namespace cellphys;
using namespace cellphys::test_support;
using spu::ComputeWorker;
using spu::Integrator;
using spu::IslandBuilder;
using spu::IslandReport;
using spu::IslandStatus;
using Bytes = std::vector<unsigned char>;

constexpr int kRefBodies = 65;

Bytes reference_image(Integrator integ = Integrator::implicit_split, uint32_t solver = 0, float tol = 1e-3f,
                      uint32_t max_halvings = 8) {
  IslandBuilder ib;
  ib.set_integrator(integ);
  ib.set_solver(solver);
  ib.set_tolerance(tol);
  ib.set_max_halvings(max_halvings);
  cellphys::testing::build_reference_island(ib);
  return ib.finish();
}

int bodies_of(const Bytes& img) { return int(reinterpret_cast<const gen::Island_Header*>(img.data())->num_bodies); }

struct Stepped {
  IslandReport report;
  Bytes result;
};

Stepped step_image(const Bytes& img, size_t local_store = spu::LocalStore::kDefaultCapacity, int fill = 0) {
  ComputeWorker w(local_store);
  Stepped s;
  s.result.assign(spu::result_bytes(uint32_t(bodies_of(img))), static_cast<unsigned char>(fill));
  s.report = w.step(img.data(), img.size(), s.result.data(), s.result.size());
  return s;
}

/// Every body's (dv, dw) of a result, stacked.
std::vector<double> deltas(const Bytes& res, int n) {
  std::vector<double> d;
  for (int i = 0; i < n; ++i) {
    const gen::Rigid_Body_Step s = result_step(res, n, i);
    for (int k = 0; k < 3; ++k) d.push_back(s.delta_velocity[k]);
    for (int k = 0; k < 3; ++k) d.push_back(s.delta_angular_velocity[k]);
  }
  return d;
}

double rel_diff(const std::vector<double>& a, const std::vector<double>& ref) {
  double num = 0, den = 0;
  for (size_t k = 0; k < a.size(); ++k) num += (a[k] - ref[k]) * (a[k] - ref[k]), den += ref[k] * ref[k];
  return std::sqrt(num / std::max(den, 1e-300));
}

bool result_bodies_equal_input(const Bytes& res, const Bytes& img) {
  const int n = bodies_of(img);
  return std::memcmp(res.data() + result_bodies_offset(n), image_bodies(img), size_t(n) * sizeof(gen::Rigid_Body)) == 0;
}

// ---- islands ------------------------------------------------------------------------------------

// A chain of n links (0.2 m long, 1 kg) joined by stiff point_to_point joints (1e6 N/m), the
// first to the world, each joint starting 5 cm open and the links spinning: a stiff,
// non-symmetric system on which the reference design's iteration limit (12 n) is tight.
Bytes stiff_chain(int n, float tol, uint32_t solver, uint32_t max_halvings, float h = 1.0f / 60,
                  float stiffness = 1e6f) {
  IslandBuilder ib;
  ib.set_integrator(Integrator::implicit_split);
  ib.set_solver(solver);
  ib.set_tolerance(tol);
  ib.set_max_halvings(max_halvings);
  ib.set_step(h);
  for (int i = 0; i < n; ++i) {
    Rigid_Body_Fields b = make_box(1.0, 0.02, 0.05, 0.1);
    b.position[0] = 0.03f * i;
    b.position[2] = -(2 * i + 1) * 0.1f;
    b.angular_velocity[0] = 1.0f;
    ib.add_body(b);
  }
  for (int i = 0; i < n; ++i) {
    gen::Point_To_Point_Constraint_Force j{};
    j.point_a[0] = 0.02f, j.point_a[2] = 0.1f;
    j.stiffness = stiffness, j.damping = 1e3f;
    j.body_a = i;
    j.body_b = i - 1;  // -1 for the first: a world point at the origin
    if (i > 0) j.point_b[2] = -0.1f;
    ib.add(gen::ForceType::point_to_point, j);
  }
  ib.add_global(gen::ForceType::gravity);
  return ib.finish();
}

// A random, well-posed island: n boxes joined by a spanning tree of springs plus extra
// springs and world anchors, every spring stretched or compressed so the forces are O(1-100 N).
Bytes random_spring_island(std::mt19937& rng, Integrator integ, uint32_t solver, float tol) {
  std::uniform_real_distribution<double> U(0.0, 1.0);
  auto sym = [&](double a) { return float(a * (2 * U(rng) - 1)); };
  const int n = 2 + int(rng() % 9);
  IslandBuilder ib;
  ib.set_integrator(integ);
  ib.set_solver(solver);
  ib.set_tolerance(tol);
  std::vector<Rigid_Body_Fields> bodies;
  for (int i = 0; i < n; ++i) {
    Rigid_Body_Fields b = make_box(0.5 + 4.5 * U(rng), 0.05 + 0.2 * U(rng), 0.05 + 0.2 * U(rng), 0.05 + 0.2 * U(rng));
    for (int k = 0; k < 3; ++k) b.position[k] = sym(1.5), b.velocity[k] = sym(1.0), b.angular_velocity[k] = sym(2.0);
    const Quatd q = quat_exp(Vec3d{sym(3.0), sym(3.0), sym(3.0)});
    b.orientation[0] = float(q.w), b.orientation[1] = float(q.x), b.orientation[2] = float(q.y), b.orientation[3] = float(q.z);
    bodies.push_back(b);
    ib.add_body(b);
  }
  auto spring = [&](int a, int b) {
    gen::Spring_Force f{};
    for (int k = 0; k < 3; ++k) f.point_a[k] = sym(0.05), f.point_b[k] = b < 0 ? sym(2.0) : sym(0.05);
    f.stiffness = float(50.0 + 1950.0 * U(rng));
    f.damping = float(20.0 * U(rng));
    const Vec3d pa = world_point(bodies[a], f.point_a);
    const Vec3d pb = b < 0 ? Vec3d::load(f.point_b) : world_point(bodies[b], f.point_b);
    f.rest_length = float(norm(pa - pb) * (0.7 + 0.6 * U(rng)));
    f.body_a = a, f.body_b = b;
    ib.add(gen::ForceType::spring, f);
  };
  for (int i = 1; i < n; ++i) spring(i, int(rng() % i));
  for (int e = 0; e < n / 2; ++e) {
    const int a = int(rng() % n), b = int(rng() % n);
    if (a != b) spring(a, b);
  }
  spring(int(rng() % n), -1);
  ib.add_global(gen::ForceType::gravity);
  return ib.finish();
}

// ---- 8. iterative solvers agree with the direct one ---------------------------------------------

TEST(Solvers, CgsAndBicgstabAgreeWithDirectOnTheReferenceIsland) {
  const Stepped direct = step_image(reference_image(Integrator::implicit_split, 2, 1e-6f));
  ASSERT_EQ(direct.report.status, IslandStatus::ok);
  const auto ref = deltas(direct.result, kRefBodies);
  for (uint32_t solver : {0u, 1u}) {
    const std::string tag = solver == 0 ? "cgs" : "bicgstab";
    const Stepped s = step_image(reference_image(Integrator::implicit_split, solver, 1e-6f));
    ASSERT_EQ(s.report.status, IslandStatus::ok) << tag;
    EXPECT_EQ(s.report.halvings, 0u) << tag;
    EXPECT_EQ(s.report.solver_code, 0u) << tag;
    const double d = rel_diff(deltas(s.result, kRefBodies), ref);
    record("reference_" + tag + "_1e-6_rel_diff_vs_direct", d);
    record("reference_" + tag + "_1e-6_iterations", s.report.solver_iterations);
    EXPECT_LT(d, 1e-3) << tag;
  }
  // the iteration counts of the two at the tolerances the charts use
  for (float tol : {1e-3f, 1e-4f, 1e-5f}) {
    for (uint32_t solver : {0u, 1u}) {
      const Stepped s = step_image(reference_image(Integrator::implicit_split, solver, tol));
      EXPECT_EQ(s.report.status, IslandStatus::ok);
      record(std::string("reference_") + (solver == 0 ? "cgs" : "bicgstab") + "_" + sci(tol, 1) + "_iterations",
             s.report.solver_iterations);
    }
  }
}

TEST(Solvers, CgsAndBicgstabAgreeWithDirectOnRandomSpringIslands) {
  std::mt19937 rng(20070619);
  double worst[2] = {0, 0};
  int iterations[2] = {0, 0};
  constexpr int kIslands = 40;
  for (int c = 0; c < kIslands; ++c) {
    for (Integrator integ : {Integrator::implicit_split, Integrator::implicit_euler}) {
      const auto seed = rng();
      std::mt19937 r0(seed), r1(seed), r2(seed);  // the same island three times
      const Bytes direct_img = random_spring_island(r0, integ, 2, 1e-6f);
      const Stepped direct = step_image(direct_img);
      ASSERT_EQ(direct.report.status, IslandStatus::ok) << "island " << c;
      const int n = bodies_of(direct_img);
      const auto ref = deltas(direct.result, n);
      for (uint32_t solver : {0u, 1u}) {
        std::mt19937& r = solver == 0 ? r1 : r2;
        const Stepped s = step_image(random_spring_island(r, integ, solver, 1e-6f));
        ASSERT_EQ(s.report.status, IslandStatus::ok) << "island " << c << " solver " << solver;
        // Halved only where the direct solve halves too: a step that would turn a body too far
        // past its spin is refused whatever the solver (kMaxAddedTurn), never for not converging.
        EXPECT_EQ(s.report.halvings, direct.report.halvings) << "island " << c << " solver " << solver;
        const double d = rel_diff(deltas(s.result, n), ref);
        EXPECT_LT(d, 1e-3) << "island " << c << " (" << n << " bodies) solver " << solver;
        worst[solver] = std::max(worst[solver], d);
        iterations[solver] += int(s.report.solver_iterations);
      }
    }
  }
  record("random_cgs_worst_rel_diff", worst[0]);
  record("random_bicgstab_worst_rel_diff", worst[1]);
  record("random_cgs_total_iterations", iterations[0]);
  record("random_bicgstab_total_iterations", iterations[1]);
}

TEST(Solvers, IterativeSolversDoNotDropASmallRightHandSide) {
  // A 1 kg body 10 um from its anchor on a 100 N/m spring: one implicit step must move it by
  // backward Euler like any other displacement (dv = -h k x / (1 + (h w)^2) = -1.6e-5 m/s).
  // The right-hand side h W g is 1.7e-5 m/s here: it must not be mistaken for "nothing to solve".
  for (double A : {1e-2, 1e-5}) {
    std::vector<double> ref;
    for (uint32_t solver : {2u, 0u, 1u}) {
      IslandBuilder ib;
      ib.set_solver(solver);
      ib.set_tolerance(1e-6f);
      Rigid_Body_Fields b = make_box(1.0, 0.1, 0.1, 0.1);
      b.position[0] = float(A);
      ib.add_body(b);
      gen::Point_To_Point_Constraint_Force f{};
      f.stiffness = 100.0f, f.body_a = 0, f.body_b = -1;
      ib.add(gen::ForceType::point_to_point, f);
      const Stepped s = step_image(ib.finish());
      ASSERT_EQ(s.report.status, IslandStatus::ok);
      const double h = 1.0 / 60, theta = 10.0 * h;
      const double dv = result_step(s.result, 1, 0).delta_velocity[0];
      const double expect = -h * 100.0 * A / (1.0 + theta * theta);
      EXPECT_NEAR(dv, expect, 1e-4 * std::fabs(expect))
          << "A = " << A << " m, solver " << solver << ": dv " << dv << ", backward Euler " << expect;
    }
  }
}

// A kinematic body (inverse mass and inverse inertia zero: the control side's ghost of a body
// in another part of a split island) keeps its velocity and drags the others implicitly: a
// 1 kg box on a 100 N/m joint to it, both at rest and the joint relaxed, takes the backward
// Euler step dv = h^2 k v / (m + h^2 k) towards it.
TEST(Kinematic, ABodyWithZeroInverseMassKeepsItsVelocityAndDragsTheOtherImplicitly) {
  for (uint32_t solver : {2u, 0u, 1u}) {
    IslandBuilder ib;
    ib.set_solver(solver);
    ib.set_tolerance(1e-6f);
    ib.add_body(make_box(1.0, 0.1, 0.1, 0.1));
    Rigid_Body_Fields g = make_box(1.0, 0.1, 0.1, 0.1);
    g.velocity[0] = 1.0f;
    g.inverse_mass = 0.0f;
    std::fill(g.inverse_inertia_body, g.inverse_inertia_body + 6, 0.0f);
    ib.add_body(g);
    gen::Point_To_Point_Constraint_Force f{};
    f.stiffness = 100.0f, f.body_a = 0, f.body_b = 1;
    ib.add(gen::ForceType::point_to_point, f);
    const Stepped s = step_image(ib.finish());
    ASSERT_EQ(s.report.status, IslandStatus::ok) << "solver " << solver;
    const double h = 1.0 / 60, hk = h * h * 100.0, expect = hk / (1.0 + hk);
    EXPECT_NEAR(result_step(s.result, 2, 0).delta_velocity[0], expect, 1e-4 * expect) << "solver " << solver;
    for (int k = 0; k < 3; ++k) {
      EXPECT_EQ(result_step(s.result, 2, 1).delta_velocity[k], 0.0f) << "solver " << solver;
      EXPECT_EQ(result_step(s.result, 2, 1).delta_angular_velocity[k], 0.0f) << "solver " << solver;
    }
    EXPECT_NEAR(result_body(s.result, 2, 1).position[0], h * 1.0, 1e-7) << "the kinematic body moved with its velocity";
  }
}

// ---- 9. a failing solve halves the step; a failed island leaves its state untouched ------------

TEST(Halving, UnreachableToleranceFailsAfterMaxHalvingsWithStateUntouched) {
  const Bytes img = stiff_chain(3, 1e-12f, 0, 2);
  const Stepped s = step_image(img, spu::LocalStore::kDefaultCapacity, 0xCD);
  record("stiff_chain_1e-12_solves", s.report.solves);
  record("stiff_chain_1e-12_iterations", s.report.solver_iterations);
  EXPECT_EQ(s.report.status, IslandStatus::failed);
  EXPECT_EQ(s.report.halvings, 2u);
  EXPECT_EQ(s.report.solver_code, 1u) << "the failure is the iteration limit";
  EXPECT_EQ(s.report.solves, 3u) << "h, then h/2, then h/4, each failing";
  EXPECT_EQ(s.report.substeps, 0u);
  const gen::Island_Result head = result_header(s.result);
  EXPECT_EQ(head.status, uint32_t(IslandStatus::failed));
  EXPECT_EQ(head.halvings, 2u);
  EXPECT_EQ(head.solver_code, 1u);
  EXPECT_TRUE(result_bodies_equal_input(s.result, img)) << "a failed island must carry its bodies back unchanged";
  for (int i = 0; i < 3; ++i) {
    const gen::Rigid_Body_Step st = result_step(s.result, 3, i);
    for (int k = 0; k < 3; ++k) {
      EXPECT_EQ(st.delta_velocity[k], 0.0f);
      EXPECT_EQ(st.delta_angular_velocity[k], 0.0f);
    }
  }
  // the same island with a reachable tolerance: one step, no halving
  const Stepped ok = step_image(stiff_chain(3, 1e-3f, 0, 2));
  EXPECT_EQ(ok.report.status, IslandStatus::ok);
  EXPECT_EQ(ok.report.halvings, 0u);
  EXPECT_EQ(ok.report.substeps, 1u);
  EXPECT_EQ(ok.report.solver_code, 0u);
}

TEST(Halving, SolverFailureAtHIsRecoveredByTwoHalfSteps) {
  // Stiff links with a tight tolerance: the full step runs out of iterations, the halves
  // converge. Which chain does so depends on float rounding (CGS's convergence is erratic),
  // so the first of a few candidates that halves exactly once is used; at least one must.
  int links = 0;
  float tol = 0.0f, k = 0.0f;
  uint32_t solver = 0;
  Stepped s;
  for (uint32_t sv : {0u, 1u})
    for (float stiff : {1e5f, 1e6f, 1e7f})
      for (int n : {2, 3, 4})
        for (float t : {1e-3f, 1e-4f, 3e-5f, 1e-5f}) {
          if (links) continue;
          s = step_image(stiff_chain(n, t, sv, 8, 1.0f / 60, stiff));
          if (s.report.status == IslandStatus::ok && s.report.halvings == 1 && s.report.solver_code != 0)
            links = n, tol = t, solver = sv, k = stiff;
        }
  ASSERT_GT(links, 0) << "no candidate chain needed exactly one halving";
  record("halving_chain_links", links);
  ASSERT_EQ(s.report.status, IslandStatus::ok);
  record("two_link_halvings", s.report.halvings);
  record("two_link_substeps", s.report.substeps);
  record("two_link_solves", s.report.solves);
  EXPECT_EQ(s.report.halvings, 1u);
  EXPECT_EQ(s.report.substeps, 2u);
  EXPECT_EQ(s.report.solves, 3u) << "h (failed), h/2, h/2";
  EXPECT_EQ(s.report.solver_code, 1u) << "the failure that caused the halving is reported";
  // exactly two steps of h/2, as the caller would have taken them one island at a time
  const Bytes first = stiff_chain(links, tol, solver, 0, 1.0f / 120, k);
  const Stepped a = step_image(first);
  ASSERT_EQ(a.report.status, IslandStatus::ok);
  Bytes second = first;  // the same island with the advanced bodies
  std::memcpy(second.data() + (image_bodies(second) - second.data()), a.result.data() + result_bodies_offset(links),
              links * sizeof(gen::Rigid_Body));
  {
    auto* h = reinterpret_cast<gen::Island_Header*>(second.data());
    h->checksum = spu::image_checksum(second.data() + sizeof(gen::Island_Header), second.size() - sizeof(gen::Island_Header));
  }
  const Stepped b = step_image(second);
  ASSERT_EQ(b.report.status, IslandStatus::ok) << b.report.error;
  EXPECT_EQ(b.report.halvings, 0u);
  EXPECT_EQ(std::memcmp(s.result.data() + result_bodies_offset(links), b.result.data() + result_bodies_offset(links),
                        links * sizeof(gen::Rigid_Body)),
            0)
      << "a halved step must be bit for bit two half steps";
  // and the change of velocity is over the whole step: the sum of the halves' changes
  for (int i = 0; i < links; ++i)
    for (int k = 0; k < 3; ++k)
      EXPECT_NEAR(result_step(s.result, links, i).delta_velocity[k],
                  result_step(a.result, links, i).delta_velocity[k] + result_step(b.result, links, i).delta_velocity[k], 1e-5);
}

TEST(Halving, FreeRotationThatCannotConvergeAtHIsSplit) {
  // a fast tumbling box: the midpoint fixed point of implicit_split does not converge at
  // h w ~ 8, so the kernel splits the step until it does; the split steps conserve |L| and E
  Rigid_Body_Fields b = make_box(1.0, 0.05, 0.2, 0.4);
  b.angular_velocity[0] = 300.0f, b.angular_velocity[1] = 300.0f, b.angular_velocity[2] = 300.0f;
  IslandBuilder ib;
  ib.add_body(b);
  const Bytes img = ib.finish();
  const Stepped s = step_image(img);
  ASSERT_EQ(s.report.status, IslandStatus::ok);
  record("tumbling_halvings", s.report.halvings);
  record("tumbling_substeps", s.report.substeps);
  EXPECT_GE(s.report.halvings, 1u);
  EXPECT_GE(s.report.substeps, 2u);
  EXPECT_EQ(s.report.solver_code, 0u) << "no solver failed: the rotation did";
  Rigid_Body_Fields after;
  gen::unpack(result_body(s.result, 1, 0), after);
  EXPECT_NEAR(norm(angular_momentum(after)) / norm(angular_momentum(b)), 1.0, 1e-5);
  EXPECT_NEAR(rotational_energy(after) / rotational_energy(b), 1.0, 1e-5);
}

// ---- 10. the reference island fits the reference design's budget but for its wider contacts -----------

TEST(Footprint, ReferenceIslandFitsTheSeedsBudgetButForItsWiderContacts) {
  const Bytes img = reference_image();
  const spu::IslandView v = spu::view_island(const_cast<unsigned char*>(img.data()));
  ASSERT_EQ(v.header->num_bodies, 65u);
  EXPECT_EQ(v.header->num_blocks, 134u) << "65 diagonal + 134 off-diagonal = 199 non-zero blocks";
  uint32_t contacts = 0;
  for (int s = 0; s < v.num_sections(); ++s)
    if (v.sections[s].force_type == uint32_t(gen::ForceType::contact)) contacts = v.sections[s].count;
  EXPECT_EQ(contacts, 400u);
  const Stepped s = step_image(img);
  ASSERT_EQ(s.report.status, IslandStatus::ok) << s.report.error;
  EXPECT_EQ(s.report.solver_code, 0u);
  EXPECT_EQ(s.report.halvings, 0u);
  EXPECT_GT(s.report.solver_iterations, 0u);
  size_t sum = 0;
  for (int r = 0; r < spu::kNumRegions; ++r) {
    record(std::string("reference_bytes_") + spu::region_name(spu::Region(r)), double(s.report.footprint.bytes[r]), 8);
    sum += s.report.footprint.bytes[r];
  }
  record("reference_footprint_total", double(s.report.footprint.total), 8);
  record("reference_local_store_peak", double(s.report.local_store_peak), 8);
  EXPECT_EQ(sum, s.report.footprint.total);
  // The reference design's budget is 126020 B, double buffering included; with its 48 B contacts the
  // island took 124512 B. The soft contact's 80 B (its anchor, mass, load and sticking) add 32 B to each
  // of the 400 contacts in the input and again in its double buffer, 25600 B, and the contact kernel's
  // 11 more inputs (the new fields and globals) 352 B of scratch (8 lanes of 4 B): 150464 B measured. Everything else keeps the budget.
  const size_t wider_contacts = 2 * size_t{contacts} * (sizeof(gen::Contact_Force) - 48);
  EXPECT_EQ(wider_contacts, 25600u);
  EXPECT_LE(s.report.footprint.total - wider_contacts, 126020u) << "the reference design's figure, but for the contacts";
  EXPECT_LE(s.report.footprint.total, 150464u) << "measured with 80 B contacts";
  EXPECT_LE(s.report.local_store_peak, s.report.footprint.total) << "the accounting must bound the real use";
  EXPECT_EQ(result_header(s.result).local_store_bytes, uint32_t(s.report.footprint.total));
}

TEST(Footprint, AccountingBoundsThePeakForEveryIntegratorAndSolver) {
  for (int integ = 0; integ < spu::kNumIntegrators; ++integ)
    for (uint32_t solver : {0u, 1u, 2u}) {
      const Stepped s = step_image(reference_image(Integrator(integ), solver));
      const std::string tag = std::string(spu::integrator_name(Integrator(integ))) + "/" + std::to_string(solver);
      EXPECT_NE(s.report.status, IslandStatus::does_not_fit) << tag;
      EXPECT_NE(s.report.status, IslandStatus::malformed) << tag;
      EXPECT_LE(s.report.local_store_peak, s.report.footprint.total) << tag;
      EXPECT_LE(s.report.footprint.total, spu::LocalStore::kDefaultCapacity) << tag;
      if (solver == 0) record("reference_footprint_" + std::string(spu::integrator_name(Integrator(integ))),
                              double(s.report.footprint.total), 8);
    }
}

TEST(Footprint, AnIslandFitsALocalStoreOfExactlyItsFootprint) {
  const Bytes img = reference_image();
  const size_t need = step_image(img).report.footprint.total;
  const Stepped exact = step_image(img, need);
  EXPECT_EQ(exact.report.status, IslandStatus::ok) << exact.report.error;
  const Stepped short_by_one = step_image(img, need - 1);
  EXPECT_EQ(short_by_one.report.status, IslandStatus::does_not_fit);
}

// ---- 11. an island that does not fit is refused, untouched ---------------------------------------

TEST(Refusal, FourHundredBodyChainDoesNotFitA64KiBLocalStore) {
  IslandBuilder ib;
  constexpr int kN = 400;
  for (int i = 0; i < kN; ++i) {
    Rigid_Body_Fields b = make_box(1.0, 0.1, 0.1, 0.1);
    b.position[0] = 0.25f * i;
    b.velocity[1] = 0.01f * i;
    ib.add_body(b);
  }
  for (int i = 1; i < kN; ++i) {
    gen::Spring_Force f{};
    f.stiffness = 1000.0f, f.rest_length = 0.25f, f.body_a = i, f.body_b = i - 1;
    ib.add(gen::ForceType::spring, f);
  }
  ib.add_global(gen::ForceType::gravity);
  const Bytes img = ib.finish();
  const Stepped s = step_image(img, 64 * 1024, 0xCD);
  EXPECT_EQ(s.report.status, IslandStatus::does_not_fit);
  record("chain400_footprint_total", double(s.report.footprint.total), 8);
  record("chain400_error", s.report.error);
  EXPECT_GT(s.report.footprint.total, 64u * 1024u);
  EXPECT_NE(s.report.error.find(std::to_string(s.report.footprint.total)), std::string::npos)
      << "the error names the bytes needed: " << s.report.error;
  EXPECT_NE(s.report.error.find("65536"), std::string::npos) << "and the capacity: " << s.report.error;
  EXPECT_EQ(s.report.solves, 0u);
  EXPECT_EQ(s.report.solver_iterations, 0u);
  EXPECT_EQ(s.report.substeps, 0u);
  const gen::Island_Result head = result_header(s.result);
  EXPECT_EQ(head.magic, spu::kResultMagic);
  EXPECT_EQ(head.status, uint32_t(IslandStatus::does_not_fit));
  EXPECT_TRUE(result_bodies_equal_input(s.result, img))
      << "kernel.h: a refused island's result carries its bodies unchanged";
}

// ---- 12. malformed islands are refused ----------------------------------------------------------------

Bytes small_island(float vy = 0.5f) {
  IslandBuilder ib;
  for (int i = 0; i < 2; ++i) {
    Rigid_Body_Fields b = make_box(1.0, 0.25, 0.25, 0.25);
    b.position[2] = 0.25f + 0.6f * i;
    b.velocity[1] = vy;
    ib.add_body(b);
  }
  gen::Contact_Force_Fields c;
  c.point[2] = 0.5f, c.normal[2] = 1.0f, c.penetration = 0.001f, c.friction = 0.5f, c.body_a = 0, c.body_b = 1;
  gen::Contact_Force packed;
  gen::pack(c, packed);
  ib.add(gen::ForceType::contact, packed);
  ib.add_global(gen::ForceType::gravity);
  return ib.finish();
}

void expect_malformed(const Bytes& img, size_t bytes, const std::string& why_contains, const char* what) {
  ComputeWorker w;
  Bytes res(spu::result_bytes(2), 0xCD);
  const IslandReport r = w.step(img.data(), bytes, res.data(), res.size());
  EXPECT_EQ(r.status, IslandStatus::malformed) << what << ": " << spu::status_name(r.status);
  EXPECT_NE(r.error.find(why_contains), std::string::npos) << what << ": error \"" << r.error << "\"";
  EXPECT_EQ(r.solves, 0u) << what;
  EXPECT_EQ(result_header(res).status, uint32_t(IslandStatus::malformed)) << what;
  record(std::string("malformed_") + what, r.error);
}

TEST(Refusal, MalformedIslandsAreRefused) {
  const Bytes good = small_island();
  ASSERT_EQ(spu::validate_island(good.data(), good.size()), "");
  ASSERT_EQ(step_image(good).report.status, IslandStatus::ok);
  {
    Bytes img = good;
    img[offsetof(gen::Island_Header, checksum)] ^= 0x01;
    expect_malformed(img, img.size(), "checksum", "flipped_checksum_byte");
  }
  {
    Bytes img = good;
    img[image_bodies(img) - img.data() + offsetof(gen::Rigid_Body, mass)] ^= 0x10;  // a corrupted transfer
    expect_malformed(img, img.size(), "checksum", "flipped_body_byte");
  }
  {
    Bytes img = good;
    img[0] ^= 0xFF;
    expect_malformed(img, img.size(), "magic", "wrong_magic");
  }
  expect_malformed(good, good.size() - 16, "bytes", "truncated_image");
  expect_malformed(good, 32, "header", "shorter_than_a_header");
  {
    // a contact naming body 7 of a 2-body island: the builder does not check, the kernel must
    IslandBuilder ib;
    for (int i = 0; i < 2; ++i) ib.add_body(make_box(1.0, 0.25, 0.25, 0.25));
    gen::Contact_Force_Fields c;
    c.normal[2] = 1.0f, c.penetration = 0.001f, c.friction = 0.5f, c.body_a = 0, c.body_b = 7;
    gen::Contact_Force packed;
    gen::pack(c, packed);
    ib.add(gen::ForceType::contact, packed);
    const Bytes img = ib.finish();
    expect_malformed(img, img.size(), "body b 7", "contact_body_out_of_range");
  }
  {
    const Bytes img = small_island(std::numeric_limits<float>::quiet_NaN());
    expect_malformed(img, img.size(), "non-finite", "nan_velocity");
  }
  {
    // a non-finite parameter is named, with its instance; a world contact's body b of -1
    // (all exponent bits set, as a NaN's) is not a parameter
    IslandBuilder ib;
    ib.add_body(make_box(1.0, 0.25, 0.25, 0.25));
    for (int k = 0; k < 3; ++k) {
      gen::Contact_Force_Fields c;
      c.normal[2] = 1.0f, c.penetration = 0.001f, c.friction = 0.5f, c.body_a = 0, c.body_b = -1;
      if (k == 2) c.friction = std::numeric_limits<float>::infinity();
      gen::Contact_Force packed;
      gen::pack(c, packed);
      ib.add(gen::ForceType::contact, packed);
    }
    const Bytes img = ib.finish();
    expect_malformed(img, img.size(), "contact instance 2: friction is not finite", "infinite_friction");
  }
}

// ---- 13. DMA rules --------------------------------------------------------------------------------------

TEST(Dma, IllegalTransfersThrow) {
  spu::LocalStore ls(64 * 1024);
  spu::Dma dma(ls);
  auto* local = static_cast<unsigned char*>(ls.allocate(1024, 128, spu::Region::input));
  ASSERT_NE(local, nullptr);
  alignas(16) static unsigned char main_mem[1024];
  EXPECT_THROW(dma.get(local + 8, main_mem, 64, 1), spu::DmaError) << "misaligned local address";
  EXPECT_THROW(dma.get(local, main_mem + 4, 64, 1), spu::DmaError) << "misaligned main address";
  EXPECT_THROW(dma.put(main_mem + 8, local, 64, 1), spu::DmaError) << "misaligned main address (put)";
  EXPECT_THROW(dma.get(local, main_mem, 24, 1), spu::DmaError) << "24 bytes is not a legal size";
  EXPECT_THROW(dma.get(local, main_mem, 0, 1), spu::DmaError) << "0 bytes is not a legal size";
  EXPECT_THROW(dma.get(local, main_mem, 3, 1), spu::DmaError) << "3 bytes is not a legal size";
  EXPECT_THROW(dma.get(local, main_mem, 64, 32), spu::DmaError) << "tags are 0..31";
  EXPECT_THROW(dma.get(main_mem, main_mem + 512, 64, 1), spu::DmaError) << "the local side is not in the local store";
  EXPECT_THROW(dma.put(main_mem, main_mem + 512, 64, 1), spu::DmaError) << "put from outside the local store";
  EXPECT_THROW(dma.get(ls.base() + ls.capacity() - 16, main_mem, 32, 1), spu::DmaError)
      << "runs past the end of the local store";
  EXPECT_EQ(dma.pending(), 0) << "a refused transfer is not queued";
  // the legal small sizes and tag 31
  for (size_t n : {1, 2, 4, 8, 16, 48}) EXPECT_NO_THROW(dma.get(local, main_mem, n, 31)) << n;
  dma.wait_all();
}

TEST(Dma, LargeTransferIsSplitAndArrivesOnlyAfterWait) {
  constexpr size_t kBytes = 40 * 1024;
  spu::LocalStore ls(64 * 1024);
  spu::Dma dma(ls);
  auto* local = static_cast<unsigned char*>(ls.allocate(kBytes, 128, spu::Region::input));
  ASSERT_NE(local, nullptr);
  std::memset(local, 0, kBytes);
  std::vector<unsigned char> src(kBytes + 16), back(kBytes + 16, 0);
  unsigned char* s = src.data() + (16 - reinterpret_cast<uintptr_t>(src.data()) % 16) % 16;
  unsigned char* d = back.data() + (16 - reinterpret_cast<uintptr_t>(back.data()) % 16) % 16;
  for (size_t i = 0; i < kBytes; ++i) s[i] = static_cast<unsigned char>((i * 131 + 7) & 0xFF);
  dma.get(local, s, kBytes, 5);
  EXPECT_EQ(dma.pending(), 3) << "16 KiB + 16 KiB + 8 KiB";
  EXPECT_EQ(dma.bytes_in(), kBytes);
  EXPECT_TRUE(std::all_of(local, local + kBytes, [](unsigned char c) { return c == 0; }))
      << "nothing arrives before wait()";
  dma.wait(1u << 6);  // another tag: still nothing
  EXPECT_EQ(dma.pending(), 3);
  EXPECT_EQ(local[0], 0);
  dma.wait(1u << 5);
  EXPECT_EQ(dma.pending(), 0);
  EXPECT_EQ(std::memcmp(local, s, kBytes), 0);
  // and back out
  dma.put(d, local, kBytes, 9);
  EXPECT_EQ(dma.pending(), 3);
  EXPECT_TRUE(std::all_of(d, d + kBytes, [](unsigned char c) { return c == 0; }));
  dma.wait(1u << 9);
  EXPECT_EQ(std::memcmp(d, s, kBytes), 0);
  EXPECT_EQ(dma.bytes_out(), kBytes);
}

// ---- 14. local store -------------------------------------------------------------------------------------

TEST(LocalStore, AllocationPastCapacityReturnsNull) {
  spu::LocalStore ls(4096);
  EXPECT_EQ(ls.capacity(), 4096u);
  void* a = ls.allocate(4000, 32, spu::Region::vectors);
  ASSERT_NE(a, nullptr);
  EXPECT_EQ(reinterpret_cast<uintptr_t>(a) % 32, 0u);
  EXPECT_EQ(ls.allocate(200, 32, spu::Region::vectors), nullptr);
  EXPECT_EQ(ls.used(), 4000u) << "a refused allocation takes nothing";
  EXPECT_NE(ls.allocate(96, 16, spu::Region::vectors), nullptr) << "what is left is still usable";
  EXPECT_EQ(ls.allocate(1, 1, spu::Region::vectors), nullptr);
  EXPECT_THROW(spu::LocalStore(512), std::invalid_argument);
}

TEST(LocalStore, ReleaseFreesAndPeakTracksTheMaximum) {
  spu::LocalStore ls(64 * 1024);
  EXPECT_EQ(reinterpret_cast<uintptr_t>(ls.base()) % spu::LocalStore::kAlign, 0u);
  ASSERT_NE(ls.allocate(1000, 16, spu::Region::input), nullptr);
  const size_t mark = ls.used();
  ASSERT_NE(ls.allocate(5000, 32, spu::Region::blocks), nullptr);
  ASSERT_NE(ls.allocate(3000, 128, spu::Region::scratch), nullptr);
  const size_t high = ls.used();
  EXPECT_GE(ls.region_bytes()[int(spu::Region::blocks)], 5000u);
  EXPECT_GE(ls.region_bytes()[int(spu::Region::scratch)], 3000u);
  EXPECT_EQ(ls.peak(), high);
  ls.release(mark);
  EXPECT_EQ(ls.used(), mark);
  EXPECT_EQ(ls.region_bytes()[int(spu::Region::blocks)], 0u);
  EXPECT_EQ(ls.region_bytes()[int(spu::Region::scratch)], 0u);
  EXPECT_EQ(ls.region_bytes()[int(spu::Region::input)], 1000u);
  EXPECT_EQ(ls.peak(), high) << "the peak survives a release";
  ASSERT_NE(ls.allocate(100, 16, spu::Region::vectors), nullptr);
  EXPECT_EQ(ls.peak(), high) << "a smaller allocation does not raise it";
  ASSERT_NE(ls.allocate(20000, 16, spu::Region::vectors), nullptr);
  EXPECT_EQ(ls.peak(), ls.used());
  EXPECT_GT(ls.peak(), high);
  ls.reset();
  EXPECT_EQ(ls.used(), 0u);
  for (int r = 0; r < spu::kNumRegions; ++r) EXPECT_EQ(ls.region_bytes()[r], 0u) << spu::region_name(spu::Region(r));
  ls.reset_peak();
  EXPECT_EQ(ls.peak(), 0u);
  // the kernel's own use is all released after a step
  ComputeWorker w;
  const Bytes img = reference_image();
  Bytes res(spu::result_bytes(kRefBodies));
  const IslandReport r = w.step(img.data(), img.size(), res.data(), res.size());
  EXPECT_EQ(r.local_store_peak, w.local_store().peak());
  EXPECT_EQ(w.dma().pending(), 0);
}

// ---- 15. determinism and the result's own contract ------------------------------------------------------

TEST(Determinism, SteppingTheSameIslandTwiceGivesIdenticalBytes) {
  for (int integ = 0; integ < spu::kNumIntegrators; ++integ) {
    const Bytes img = reference_image(Integrator(integ));
    ComputeWorker w;
    Bytes a(spu::result_bytes(kRefBodies), 0), b(spu::result_bytes(kRefBodies), 0xFF);
    const IslandReport ra = w.step(img.data(), img.size(), a.data(), a.size());
    const IslandReport rb = w.step(img.data(), img.size(), b.data(), b.size());  // same worker, reused
    const Stepped c = step_image(img, spu::LocalStore::kDefaultCapacity, 0x55);  // a fresh worker
    EXPECT_EQ(a, b) << spu::integrator_name(Integrator(integ));
    EXPECT_EQ(a, c.result) << spu::integrator_name(Integrator(integ));
    EXPECT_EQ(ra.solver_iterations, rb.solver_iterations);
    EXPECT_EQ(ra.status, c.report.status);
  }
  std::mt19937 rng(7);
  for (int k = 0; k < 10; ++k) {
    const Bytes img = random_spring_island(rng, Integrator::rosenbrock, 0, 1e-3f);
    EXPECT_EQ(step_image(img, spu::LocalStore::kDefaultCapacity, 0).result,
              step_image(img, spu::LocalStore::kDefaultCapacity, 0xAA).result);
  }
}

// Every image as one step_batch, results prefilled with 0xEE (as step_image(..., 0xEE) fills them).
void step_all(ComputeWorker& w, const std::vector<Bytes>& images, std::vector<Bytes>& results,
              std::vector<IslandReport>& reports) {
  results.assign(images.size(), Bytes{});
  std::vector<spu::IslandJob> jobs(images.size());
  for (size_t k = 0; k < images.size(); ++k) {
    results[k].assign(spu::result_bytes(uint32_t(bodies_of(images[k]))), 0xEE);
    jobs[k] = {images[k].data(), images[k].size(), results[k].data(), results[k].size()};
  }
  reports.assign(images.size(), IslandReport{});
  w.step_batch(jobs.data(), jobs.size(), reports.data());
}

TEST(Determinism, ABatchGivesTheSameBytesAsSteppingEachIslandAlone) {
  // double-buffered batches (kernel.h: "results are identical to stepping each alone"),
  // with islands of several sizes and integrators, a malformed one and one that does not fit
  std::vector<Bytes> images;
  for (int integ = 0; integ < spu::kNumIntegrators; ++integ) images.push_back(reference_image(Integrator(integ)));
  std::mt19937 rng(11);
  for (int k = 0; k < 6; ++k)
    images.push_back(random_spring_island(rng, k % 2 ? Integrator::implicit_euler : Integrator::rk4, k % 3, 1e-4f));
  images.push_back(stiff_chain(3, 1e-12f, 0, 2));  // fails after two halvings
  {
    Bytes bad = small_island();
    bad[offsetof(gen::Island_Header, checksum)] ^= 0x01;
    images.push_back(bad);
  }
  {
    IslandBuilder ib;
    for (int i = 0; i < 400; ++i) ib.add_body(make_box(1.0, 0.1, 0.1, 0.1));
    images.push_back(ib.finish());  // 400 bodies: over 256 KiB
  }
  images.push_back(small_island());
  // every order: same-size neighbours (the overlapped path) and mixed sizes
  for (int pass = 0; pass < 2; ++pass) {
    if (pass == 1) std::reverse(images.begin(), images.end());
    std::vector<Bytes> results;
    std::vector<IslandReport> reports;
    ComputeWorker w;
    step_all(w, images, results, reports);
    for (size_t k = 0; k < images.size(); ++k) {
      const Stepped alone = step_image(images[k], spu::LocalStore::kDefaultCapacity, 0xEE);
      EXPECT_EQ(reports[k].status, alone.report.status) << "pass " << pass << " island " << k;
      EXPECT_EQ(reports[k].solver_iterations, alone.report.solver_iterations) << "pass " << pass << " island " << k;
      EXPECT_EQ(reports[k].halvings, alone.report.halvings) << "pass " << pass << " island " << k;
      size_t first = 0;
      while (first < results[k].size() && results[k][first] == alone.result[first]) ++first;
      EXPECT_EQ(first, results[k].size()) << "pass " << pass << " island " << k << " ("
                                          << spu::status_name(alone.report.status) << "): first differing byte "
                                          << first << " of " << results[k].size() << " (bodies start at "
                                          << result_bodies_offset(bodies_of(images[k])) << ")";
    }
    EXPECT_EQ(w.dma().pending(), 0);
  }
}

// A box resting on (or pressed into) the ground on 1-4 world contacts, moving a little: the
// one-body island a sparse world is mostly made of.
Bytes box_on_ground(std::mt19937& rng, Integrator integ) {
  std::uniform_real_distribution<double> U(0.0, 1.0);
  const float half = float(0.1 + 0.4 * U(rng)), mass = float(0.5 + 50 * U(rng));
  IslandBuilder ib;
  ib.set_integrator(integ);
  Rigid_Body_Fields b = make_box(mass, half, half, half);
  b.position[2] = half - 0.002f * float(U(rng));
  for (int k = 0; k < 3; ++k) b.velocity[k] = float(0.5 * (2 * U(rng) - 1)), b.angular_velocity[k] = float(2 * U(rng) - 1);
  ib.add_body(b);
  const int corners = 1 + int(rng() % 4);
  for (int c = 0; c < corners; ++c) {
    gen::Contact_Force_Fields f;
    f.point[0] = b.position[0] + (c & 1 ? half : -half), f.point[1] = b.position[1] + (c & 2 ? half : -half);
    f.normal[2] = 1.0f, f.penetration = float(0.003 * U(rng)), f.friction = float(0.2 + 0.8 * U(rng));
    f.mass = mass / float(corners), f.hold = 0.001f, f.body_a = 0, f.body_b = -1;
    gen::Contact_Force packed;
    gen::pack(f, packed);
    ib.add(gen::ForceType::contact, packed);
  }
  ib.add_global(gen::ForceType::gravity);
  return ib.finish();
}

// n boxes in a line, spring k from box k to box k + 1 and the last to the world: box k + 1 is
// body b of spring k and body a of spring k + 1, so within a batch its sums depend on which
// lane each spring sits in (force_eval.cpp, scatter_batch).
Bytes spring_line(std::mt19937& rng, int n) {
  std::uniform_real_distribution<double> U(0.0, 1.0);
  IslandBuilder ib;
  for (int i = 0; i < n; ++i) {
    Rigid_Body_Fields b = make_box(0.5 + 4.5 * U(rng), 0.1, 0.1, 0.1);
    b.position[0] = 0.3f * float(i) + float(0.05 * U(rng)), b.position[2] = float(0.05 * U(rng));
    b.velocity[2] = float(2 * U(rng) - 1);
    ib.add_body(b);
  }
  for (int i = 0; i < n; ++i) {
    gen::Spring_Force f{};
    f.stiffness = float(100 + 900 * U(rng)), f.damping = float(5 * U(rng)), f.rest_length = 0.3f;
    f.body_a = i, f.body_b = i + 1 < n ? i + 1 : -1;
    if (i + 1 == n) f.point_b[0] = 0.3f * float(n);
    ib.add(gen::ForceType::spring, f);
  }
  ib.add_global(gen::ForceType::gravity);
  return ib.finish();
}

// A hub box with 2-6 spokes, the springs pointing in and out by turns: the hub is body a of
// some and body b of others, so its sum of three or more terms depends on whether a batch
// splits the island's springs (force_eval.cpp, push_section). Few springs: islands of this
// kind share batches.
Bytes spring_star(std::mt19937& rng) {
  std::uniform_real_distribution<double> U(0.0, 1.0);
  const int spokes = 2 + int(rng() % 5);
  IslandBuilder ib;
  for (int i = 0; i <= spokes; ++i) {
    Rigid_Body_Fields b = make_box(0.5 + 4.5 * U(rng), 0.1, 0.1, 0.1);
    const double angle = 6.283185307179586 * i / spokes;
    if (i > 0) b.position[0] = float(0.3 * std::cos(angle)), b.position[1] = float(0.3 * std::sin(angle));
    b.position[2] = float(0.05 * U(rng));
    for (int k = 0; k < 3; ++k) b.velocity[k] = float(2 * U(rng) - 1);
    ib.add_body(b);
  }
  for (int i = 1; i <= spokes; ++i) {
    gen::Spring_Force f{};
    f.stiffness = float(100 + 900 * U(rng)), f.damping = float(5 * U(rng)), f.rest_length = 0.25f;
    f.body_a = i % 2 ? 0 : i, f.body_b = i % 2 ? i : 0;
    ib.add(gen::ForceType::spring, f);
  }
  ib.add_global(gen::ForceType::gravity);
  return ib.finish();
}

// A brick spun so fast (hundreds of rad/s) that its free rotation's fixed point does not
// converge at the full step: the island's first step fails in the commit's rotation, with its
// lanes shared with other islands' bodies, and is halved.
Bytes spinning_brick(std::mt19937& rng) {
  std::uniform_real_distribution<double> U(0.0, 1.0);
  IslandBuilder ib;
  Rigid_Body_Fields b = make_box(1.0 + 4.0 * U(rng), 0.4, 0.1, 0.2);
  for (int k = 0; k < 3; ++k) b.angular_velocity[k] = float(300 * (2 * U(rng) - 1));
  ib.add_body(b);
  ib.add_global(gen::ForceType::gravity);
  return ib.finish();
}

TEST(Determinism, SmallIslandsSteppedTogetherGiveTheBytesEachGetsAlone) {
  // step_batch integrates runs of small implicit islands together, their one-body kernels'
  // SIMD lanes filled across islands (kernel.h): every island's result must be the bytes it
  // gets alone. Boxes on the ground, two-box contact islands, spring islands and lines of 2-14 bodies,
  // chains whose first step fails in the solve and halves, bricks whose first step fails in the
  // rotation and halves, spring stars whose hubs' sums depend on how batches split their
  // springs, on both implicit integrators, with a malformed island and a Runge-Kutta one
  // breaking the runs.
  std::mt19937 rng(23);
  std::vector<Bytes> images;
  for (int k = 0; k < 60; ++k) {
    const Integrator integ = k < 40 ? Integrator::implicit_split : Integrator::implicit_euler;
    switch (k % 6) {
      case 0: images.push_back(k % 12 ? random_spring_island(rng, integ, 0, 1e-3f) : spring_line(rng, 6 + k % 7)); break;
      case 4: images.push_back(spring_line(rng, 3 + k % 9)); break;
      case 1: images.push_back(small_island(float(k) * 0.1f)); break;
      case 2: images.push_back(k % 12 == 2 ? stiff_chain(2, 1e-12f, 0, 2) : box_on_ground(rng, integ)); break;
      case 3: images.push_back(k % 12 == 3 && integ == Integrator::implicit_split ? spinning_brick(rng) : box_on_ground(rng, integ)); break;
      default: images.push_back(k % 12 == 5 ? spring_star(rng) : box_on_ground(rng, integ)); break;
    }
  }
  // runs of stars: each shares a batch with the last when its springs fit the lanes left
  for (int k = 0; k < 12; ++k) images.insert(images.begin() + 45, spring_star(rng));
  Bytes bad = small_island();
  bad[offsetof(gen::Island_Header, checksum)] ^= 0x01;
  images.insert(images.begin() + 17, bad);
  images.insert(images.begin() + 33, reference_image(Integrator::rk4));
  std::vector<Bytes> results;
  std::vector<IslandReport> reports;
  ComputeWorker w;
  step_all(w, images, results, reports);
  size_t halved = 0, together = 0, spun_halved = 0;
  for (size_t k = 0; k < images.size(); ++k) {
    const Stepped alone = step_image(images[k], spu::LocalStore::kDefaultCapacity, 0xEE);
    EXPECT_EQ(reports[k].status, alone.report.status) << "island " << k;
    EXPECT_EQ(reports[k].solver_iterations, alone.report.solver_iterations) << "island " << k;
    EXPECT_EQ(reports[k].solves, alone.report.solves) << "island " << k;
    EXPECT_EQ(reports[k].halvings, alone.report.halvings) << "island " << k;
    EXPECT_EQ(reports[k].substeps, alone.report.substeps) << "island " << k;
    EXPECT_EQ(results[k], alone.result) << "island " << k << " (" << spu::status_name(alone.report.status) << ")";
    halved += alone.report.halvings > 0;
    spun_halved += alone.report.halvings > 0 && bodies_of(images[k]) == 1 && alone.report.solves > 1 &&
                   reports[k].local_store_peak > alone.report.local_store_peak;
    // held in the store with others: more than its own double-buffered footprint was in use
    together += reports[k].local_store_peak > alone.report.local_store_peak;
  }
  EXPECT_GE(halved, 3u) << "the chains' first steps must fail for the retry to be tested";
  EXPECT_GE(spun_halved, 2u) << "the spinning bricks' first steps must fail in shared lanes";
  EXPECT_GE(together, 40u) << "most islands should have been integrated together";
  EXPECT_EQ(w.dma().pending(), 0);
}

TEST(Determinism, EachIslandOfABatchGetsItsOwnAdvancedBodies) {
  // four one-body islands falling under gravity, each starting at x = k and v_y = k: the
  // result of island k must be island k's body advanced one step (x = k + h k, v_z = g h)
  constexpr int kCount = 4;
  std::vector<Bytes> images, results;
  for (int k = 1; k <= kCount; ++k) {
    IslandBuilder ib;
    Rigid_Body_Fields b = make_box(1.0, 0.1, 0.1, 0.1);
    b.position[0] = float(k), b.velocity[1] = float(k);
    ib.add_body(b);
    ib.add_global(gen::ForceType::gravity);
    images.push_back(ib.finish());
    results.emplace_back(spu::result_bytes(1), 0);
  }
  std::vector<spu::IslandJob> jobs;
  for (int k = 0; k < kCount; ++k) jobs.push_back({images[k].data(), images[k].size(), results[k].data(), results[k].size()});
  std::vector<IslandReport> reports(kCount);
  ComputeWorker w;
  w.step_batch(jobs.data(), kCount, reports.data());
  const float h = 1.0f / 60;
  for (int k = 0; k < kCount; ++k) {
    ASSERT_EQ(reports[k].status, IslandStatus::ok);
    const gen::Rigid_Body b = result_body(results[k], 1, 0);
    EXPECT_EQ(b.position[0], float(k + 1)) << "island " << k;
    EXPECT_EQ(b.velocity[1], float(k + 1)) << "island " << k;
    EXPECT_NEAR(b.velocity[2], -9.81f * h, 1e-6) << "island " << k << " was not advanced";
    EXPECT_NEAR(b.position[1], h * (k + 1), 1e-6) << "island " << k;
  }
}

TEST(Trusted, AnUnsealedImageSteppedWhereItWasPackedGivesTheSealedBytesButTheChecksums) {
  // A world's own threads step the images they pack unsealed (IslandJob::trusted): only the
  // checksums may differ from the sealed image's bytes and results, both 0.
  IslandBuilder ib;
  cellphys::testing::build_reference_island(ib);
  const Bytes sealed = ib.finish();
  Bytes unsealed;
  ib.finish(unsealed, /*seal=*/false);
  Bytes zeroed = sealed;
  std::memset(zeroed.data() + offsetof(gen::Island_Header, checksum), 0, sizeof(uint32_t));
  EXPECT_EQ(unsealed, zeroed);
  EXPECT_NE(reinterpret_cast<const gen::Island_Header*>(sealed.data())->checksum, 0u);
  EXPECT_EQ(spu::validate_island(unsealed.data(), unsealed.size(), /*sealed=*/false), "");
  EXPECT_EQ(spu::validate_island(unsealed.data(), unsealed.size()), "checksum mismatch");
  // an unsealed image that is not marked trusted is refused as any damaged one
  Bytes open_pair = small_island();
  std::memset(open_pair.data() + offsetof(gen::Island_Header, checksum), 0, sizeof(uint32_t));
  expect_malformed(open_pair, open_pair.size(), "checksum", "unsealed_untrusted");

  std::mt19937 rng(31);
  std::vector<Bytes> images;
  for (int k = 0; k < 24; ++k) {
    const Integrator integ = k % 2 ? Integrator::implicit_split : Integrator::implicit_euler;
    images.push_back(k % 8 == 3 ? spring_line(rng, 4 + k % 5) : k % 8 == 5 ? small_island(0.1f * float(k)) : box_on_ground(rng, integ));
  }
  images.push_back(reference_image());
  images.push_back(reference_image(Integrator::rk4));
  std::vector<Bytes> results;
  std::vector<IslandReport> reports;
  ComputeWorker sealed_worker, trusted_worker;
  step_all(sealed_worker, images, results, reports);
  std::vector<Bytes> open = images, open_results(images.size());
  std::vector<spu::IslandJob> jobs(images.size());
  for (size_t k = 0; k < images.size(); ++k) {
    std::memset(open[k].data() + offsetof(gen::Island_Header, checksum), 0, sizeof(uint32_t));
    open_results[k].assign(results[k].size(), 0xEE);
    jobs[k] = {open[k].data(), open[k].size(), open_results[k].data(), open_results[k].size(), /*trusted=*/true};
  }
  std::vector<IslandReport> open_reports(images.size());
  trusted_worker.step_batch(jobs.data(), jobs.size(), open_reports.data());
  for (size_t k = 0; k < images.size(); ++k) {
    ASSERT_EQ(reports[k].status, IslandStatus::ok) << "island " << k;
    EXPECT_EQ(open_reports[k].status, IslandStatus::ok) << "island " << k;
    EXPECT_EQ(open_reports[k].solver_iterations, reports[k].solver_iterations) << "island " << k;
    EXPECT_EQ(result_header(open_results[k]).checksum, 0u) << "island " << k;
    Bytes expect = results[k];
    std::memset(expect.data() + offsetof(gen::Island_Result, checksum), 0, sizeof(uint32_t));
    EXPECT_EQ(open_results[k], expect) << "island " << k;
  }
}

// image_checksum as documented, written out byte by byte: the machine's path (AVX-512 lanes in
// registers, masked loads for the tail) gives its values for every length around the block
// size and every seed tried, so images checked on one path are checked alike on another.
uint32_t image_checksum_as_defined(const unsigned char* p, size_t n, uint32_t seed) {
  uint64_t h[16];
  for (uint64_t k = 0; k < 16; ++k) h[k] = (0xCBF29CE484222325ull + 0x9E3779B97F4A7C15ull * k) ^ seed;
  for (size_t word = 0; word * 8 < n; ++word) {
    uint64_t w = 0;
    for (size_t b = 0; b < 8 && word * 8 + b < n; ++b) w |= uint64_t(p[word * 8 + b]) << (8 * b);
    h[word % 16] = (h[word % 16] ^ w) * 0x100000001B3ull;
  }
  uint64_t x = uint64_t(n) * 0x9E3779B97F4A7C15ull;
  for (uint64_t k = 0; k < 16; ++k) x ^= h[k] * (2 * k + 3);
  x ^= x >> 29;
  x *= 0xBF58476D1CE4E5B9ull;
  x ^= x >> 32;
  return static_cast<uint32_t>(x);
}

TEST(ImageChecksum, IsItsDefinitionAndSeesEveryFlippedBit) {
  std::mt19937 rng(11);
  std::vector<unsigned char> bytes(700);
  for (auto& b : bytes) b = static_cast<unsigned char>(rng());
  for (size_t offset : {size_t(0), size_t(1), size_t(13)})
    for (size_t n = 0; n + offset <= bytes.size(); n += (n < 300 ? 1 : 37))
      for (uint32_t seed : {0x811C9DC5u, 0u, 0xFFFFFFFFu}) {
        const unsigned char* p = bytes.data() + offset;
        ASSERT_EQ(spu::image_checksum(p, n, seed), image_checksum_as_defined(p, n, seed)) << n << " bytes at " << offset;
      }
  // Any one bit flipped, and one zero byte more, change it.
  std::vector<unsigned char> b(bytes.begin(), bytes.begin() + 301);
  const uint32_t sum = spu::image_checksum(b.data(), b.size());
  for (size_t i = 0; i < b.size(); ++i)
    for (int bit = 0; bit < 8; ++bit) {
      b[i] ^= static_cast<unsigned char>(1u << bit);
      ASSERT_NE(spu::image_checksum(b.data(), b.size()), sum) << "byte " << i << " bit " << bit;
      b[i] ^= static_cast<unsigned char>(1u << bit);
    }
  std::vector<unsigned char> zeros(64, 0);
  for (size_t n = 0; n < 64; ++n) ASSERT_NE(spu::image_checksum(zeros.data(), n), spu::image_checksum(zeros.data(), n + 1)) << n;
}

TEST(Result, HeaderStepsAndChecksumDescribeTheAdvancedBodies) {
  IslandBuilder ib;
  ib.set_island_id(4242);
  cellphys::testing::build_reference_island(ib);
  const Bytes img = ib.finish();
  const Stepped s = step_image(img);
  ASSERT_EQ(s.report.status, IslandStatus::ok);
  const gen::Island_Result h = result_header(s.result);
  EXPECT_EQ(h.magic, spu::kResultMagic);
  EXPECT_EQ(h.island_id, 4242u);
  EXPECT_EQ(h.num_bodies, uint32_t(kRefBodies));
  EXPECT_EQ(h.total_bytes, spu::result_bytes(kRefBodies));
  EXPECT_EQ(h.solver_iterations, s.report.solver_iterations);
  EXPECT_EQ(h.solves, s.report.solves);
  EXPECT_EQ(h.substeps, s.report.substeps);
  const size_t steps_bytes = kRefBodies * sizeof(gen::Rigid_Body_Step), bodies_bytes = kRefBodies * sizeof(gen::Rigid_Body);
  EXPECT_EQ(h.checksum, spu::image_checksum(s.result.data() + result_bodies_offset(kRefBodies), bodies_bytes,
                                         spu::image_checksum(s.result.data() + result_steps_offset(), steps_bytes)));
  const auto* in = reinterpret_cast<const gen::Rigid_Body*>(image_bodies(img));
  for (int i = 0; i < kRefBodies; ++i) {
    const gen::Rigid_Body out = result_body(s.result, kRefBodies, i);
    const gen::Rigid_Body_Step st = result_step(s.result, kRefBodies, i);
    for (int k = 0; k < 3; ++k) {
      EXPECT_EQ(st.delta_velocity[k], out.velocity[k] - in[i].velocity[k]);
      EXPECT_EQ(st.delta_angular_velocity[k], out.angular_velocity[k] - in[i].angular_velocity[k]);
    }
    // what the kernel does not integrate comes back as it went
    EXPECT_EQ(std::memcmp(&out.inertia_body, &in[i].inertia_body, sizeof(gen::Rigid_Body) - offsetof(gen::Rigid_Body, inertia_body)), 0);
    const double qn = std::hypot(std::hypot(out.orientation[0], out.orientation[1]),
                                 std::hypot(out.orientation[2], out.orientation[3]));
    EXPECT_NEAR(qn, 1.0, 1e-6);
  }
}

// The diagonal blocks' inverses eight to a lane group: every block inverted in place, one the
// straight-line inverse refuses (its translational 3x3 is zero, the block is not singular)
// by pivoting in its group, and a singular block refused.
TEST(DiagonalInverses, EveryBlockInvertedInPlaceAndASingularOneRefused) {
  using gen::kBlockFloats;
  using gen::padded;
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(-0.2f, 0.2f);
  constexpr int kCount = 11;  // a full group and three lanes of the next
  struct alignas(32) Block {  // blocks are 32-byte aligned, as in the local store
    float m[kBlockFloats];
  };
  std::vector<Block> blocks(kCount, Block{}), original;
  for (int b = 0; b < kCount; ++b)
    for (int c = 0; c < 6; ++c)
      for (int r = 0; r < 6; ++r) {
        float v = (r == c ? 1.0f : 0.0f) + u(rng);
        if (b == 9) v = (r == (c + 3) % 6) ? (r < 3 ? 1.0f : 2.0f) : 0.0f;  // [[0 I] [2I 0]]: no 3x3 pivot
        blocks[size_t(b)].m[8 * c + padded(r)] = v;
      }
  original = blocks;
  std::vector<float*> ptrs;
  for (Block& b : blocks) ptrs.push_back(b.m);
  ASSERT_TRUE(spu::invert_blocks(ptrs.data(), kCount));
  for (int b = 0; b < kCount; ++b) {
    const float* A = original[size_t(b)].m;
    const float* X = blocks[size_t(b)].m;
    for (int i = 0; i < 6; ++i)
      for (int j = 0; j < 6; ++j) {
        double s = 0;
        for (int k = 0; k < 6; ++k) s += double(A[8 * k + padded(i)]) * X[8 * j + padded(k)];
        EXPECT_NEAR(s, i == j ? 1.0 : 0.0, 1e-5) << "block " << b << " (" << i << ", " << j << ")";
      }
  }
  Block singular{};
  singular.m[0] = 1.0f;  // rank one
  float* one[1] = {singular.m};
  EXPECT_FALSE(spu::invert_blocks(one, 1));
}

// The scaling of a big system with its rows shared out (ranges taken backwards) gives the
// unshared pass's bits in every block, right-hand side and kept P; with a singular diagonal
// block both refuse it. A small system is not shared.
TEST(ScaledSystem, SharedRowsGiveTheUnsharedBitsAndRefusal) {
  using gen::kBlockFloats;
  using gen::kVecFloats;
  using gen::padded;
  std::mt19937 rng(23);
  std::uniform_real_distribution<float> u(-0.1f, 0.1f), mass(0.5f, 2.0f);
  struct alignas(32) Block {
    float m[kBlockFloats];
  };
  struct alignas(32) Vec8 {
    float v[kVecFloats];
  };
  struct System {
    spu::BlockStructure s;
    std::vector<int32_t> row_start, col;
    std::vector<gen::W_Element> w;
    std::vector<Block> diag, off, p;
    std::vector<Vec8> rhs;
  };
  auto make = [&](int n, int per_row) {
    System y;
    y.row_start.push_back(0);
    for (int i = 0; i < n; ++i) {
      for (int k = 1; k <= per_row; ++k) y.col.push_back((i + 7 * k) % n);
      y.row_start.push_back(static_cast<int32_t>(y.col.size()));
    }
    y.s.n = n, y.s.nnz = static_cast<int>(y.col.size());
    y.s.row_start = y.row_start.data(), y.s.col = y.col.data();
    y.w.assign(size_t(n), gen::W_Element{});
    y.diag.assign(size_t(n), Block{}), y.p.assign(size_t(n), Block{}), y.off.assign(y.col.size(), Block{});
    y.rhs.assign(size_t(n), Vec8{});
    for (int i = 0; i < n; ++i) {
      y.w[size_t(i)].inverse_mass = mass(rng);
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) y.w[size_t(i)].inverse_inertia_world[3 * r + c] = r == c ? mass(rng) : 0.0f;
      for (int r = 0; r < 6; ++r) y.rhs[size_t(i)].v[padded(r)] = u(rng);
    }
    for (auto* blocks : {&y.diag, &y.off})
      for (Block& b : *blocks)
        for (int c = 0; c < 6; ++c)
          for (int r = 0; r < 6; ++r) b.m[8 * c + padded(r)] = u(rng);
    return y;
  };
  auto scale = [](System& y, spu::RowSharer* sharer) {
    return spu::scale_system(y.s, y.w.data(), 1.0f / 60, y.diag[0].m, y.off[0].m, y.rhs[0].v, y.p[0].m, sharer);
  };
  auto same = [](const auto& a, const auto& b) {
    return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof a[0]) == 0;
  };
  for (int n : {40, 1100}) {
    const System start = make(n, 4);
    // copies share start's structure (s points at its arrays; the scaling only reads them)
    System alone = start, shared = start;
    test_support::BackwardSharer sharer;
    ASSERT_TRUE(scale(alone, nullptr));
    ASSERT_TRUE(scale(shared, &sharer));
    EXPECT_EQ(sharer.shares, start.s.nnz >= spu::kShareBlocks ? 2u : 0u) << n << " rows";
    EXPECT_TRUE(same(alone.diag, shared.diag)) << n << " rows: inverses";
    EXPECT_TRUE(same(alone.off, shared.off)) << n << " rows: blocks";
    EXPECT_TRUE(same(alone.rhs, shared.rhs)) << n << " rows: right-hand side";
    EXPECT_TRUE(same(alone.p, shared.p)) << n << " rows: P";
    // W = I and K_ii = I: A_ii = I - W K_ii = 0
    System bad = start;
    const int k = n - 3;
    bad.w[size_t(k)] = gen::W_Element{};
    bad.w[size_t(k)].inverse_mass = 1.0f;
    for (int r = 0; r < 3; ++r) bad.w[size_t(k)].inverse_inertia_world[4 * r] = 1.0f;
    bad.diag[size_t(k)] = Block{};
    for (int r = 0; r < 6; ++r) bad.diag[size_t(k)].m[8 * r + padded(r)] = 1.0f;
    System bad_shared = bad;
    EXPECT_FALSE(scale(bad, nullptr)) << n << " rows";
    EXPECT_FALSE(scale(bad_shared, &sharer)) << n << " rows, shared";
  }
}

}  // namespace
