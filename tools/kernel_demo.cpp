// `cellphys kernel-demo`: the reference group (65 boxes, 400 contacts) stepped through
// the compute kernel alone, and a torque-free spinning box, with a summary a person can read.
// (This was the command's default job before scene files.)
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include "runtime/spu/kernel.h"
#include "runtime/spu/rigid_motion.h"
#include "testing/reference_island.h"
#include "tools/cli.h"

namespace {

using namespace cellphys;
using namespace cellphys::gen;
using namespace cellphys::spu;

int usage(FILE* out) {
  std::fprintf(out,
               "usage: cellphys kernel-demo [--integrator NAME] [--steps N]\n"
               "  step the reference design's 65-box group and a spinning box through the compute\n"
               "  kernel alone (no world), N steps of the box (default 600)\n"
               "  integrators %s (default: %s)\n",
               integrator_names().c_str(), integrator_name(Integrator::implicit_split));
  return out == stderr ? 2 : 0;
}

double kinetic_energy(const std::vector<Rigid_Body_Fields>& bodies) {
  double e = 0;
  for (const auto& b : bodies) {
    Rigid_Body rb;
    pack(b, rb);
    const Mat3d R = quat_to_matrix(orientation(rb));
    const Vec3d wb = mul_transpose(R, Vec3d::load(b.angular_velocity));
    e += 0.5 * b.mass * (b.velocity[0] * b.velocity[0] + b.velocity[1] * b.velocity[1] + b.velocity[2] * b.velocity[2]);
    e += 0.5 * (b.inertia_body[0] * wb.x * wb.x + b.inertia_body[1] * wb.y * wb.y + b.inertia_body[2] * wb.z * wb.z);
  }
  return e;
}

// Steps an island built by `build` for `steps` steps, feeding each result back.
template <class Build>
bool run(Build build, std::vector<Rigid_Body_Fields>& bodies, int steps, Integrator integ, IslandReport* last,
         double* ms_per_step, long* iterations) {
  ComputeWorker worker;
  std::vector<unsigned char> result;
  double total_ms = 0;
  *iterations = 0;
  for (int s = 0; s < steps; ++s) {
    IslandBuilder ib;
    ib.set_integrator(integ);
    build(ib, bodies);
    const std::vector<unsigned char> img = ib.finish();
    result.assign(result_bytes(static_cast<uint32_t>(bodies.size())), 0);
    const auto t0 = std::chrono::steady_clock::now();
    *last = worker.step(img.data(), img.size(), result.data(), result.size());
    total_ms += std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    *iterations += last->solver_iterations;
    if (last->status != IslandStatus::ok) return false;
    const size_t off = result.size() - bodies.size() * sizeof(Rigid_Body);
    for (size_t i = 0; i < bodies.size(); ++i) {
      Rigid_Body rb;
      std::memcpy(&rb, result.data() + off + i * sizeof rb, sizeof rb);
      unpack(rb, bodies[i]);
    }
  }
  *ms_per_step = total_ms / steps;
  return true;
}

int demo(Integrator integ, int steps) {
  std::printf("cellphys 0.1: the compute kernel on this machine (SIMD path %s)\n\n", simd::kPathName);
  // 1. The reference group, one step, timed over repeats (median).
  IslandBuilder ref;
  ref.set_integrator(integ);
  testing::build_reference_island(ref);
  const std::vector<unsigned char> img = ref.finish();
  const IslandView v = view_island(const_cast<unsigned char*>(img.data()));
  std::vector<unsigned char> result(result_bytes(v.header->num_bodies));
  ComputeWorker worker;
  IslandReport r;
  std::vector<double> times;
  for (int k = 0; k < 101; ++k) {
    const auto t0 = std::chrono::steady_clock::now();
    r = worker.step(img.data(), img.size(), result.data(), result.size());
    times.push_back(std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t0).count());
  }
  std::sort(times.begin(), times.end());
  std::printf("reference group (the reference design's: 65 boxes in two layers, 400 contacts)\n");
  std::printf("  non-zero blocks %u, local store %zu of %zu bytes (the reference design's figure: 126,020)\n",
              v.header->num_blocks + v.header->num_bodies, r.footprint.total, LocalStore::kDefaultCapacity);
  std::printf("  one %s step: %s, %u solver iterations, median %.1f us\n\n", integrator_name(integ),
              status_name(r.status), r.solver_iterations, times[times.size() / 2]);
  const bool ok = r.status == IslandStatus::ok;
  double ms = 0;
  long iters = 0;

  // 2. A torque-free box spinning near its intermediate axis: |L| and energy must hold.
  std::vector<Rigid_Body_Fields> box = {testing::box_body(1.0f, 0.05f, 0.2f, 0.4f)};
  box[0].angular_velocity[0] = 1, box[0].angular_velocity[1] = 10, box[0].angular_velocity[2] = 1;
  const double E0 = kinetic_energy(box);
  auto L_of = [](const Rigid_Body_Fields& b) {
    Rigid_Body rb;
    pack(b, rb);
    const Mat3d I = rotate_sym(quat_to_matrix(orientation(rb)), b.inertia_body);
    const Vec3d L = mul(I, Vec3d::load(b.angular_velocity));
    return std::sqrt(L.x * L.x + L.y * L.y + L.z * L.z);
  };
  const double L0 = L_of(box[0]);
  const bool spin_ok = run(
      [](IslandBuilder& ib, const std::vector<Rigid_Body_Fields>& b) {
        ib.add_body(b[0]);
        Gyroscopic_Force g{};
        g.body_a = 0;
        ib.add(ForceType::gyroscopic, g);
      },
      box, steps, integ, &r, &ms, &iters);
  std::printf("spinning box (0.1 x 0.4 x 0.8 m, w0 = (1, 10, 1) rad/s), %d steps at 60 Hz, %s\n", steps,
              integrator_name(integ));
  if (!spin_ok) {
    std::printf("  step failed: %s\n", status_name(r.status));
    return 1;
  }
  std::printf("  |L| change %+.4f%%, energy change %+.4f%%, %.4f ms per step\n", 100 * (L_of(box[0]) / L0 - 1),
              100 * (kinetic_energy(box) / E0 - 1), ms);
  return ok ? 0 : 1;
}

}  // namespace

namespace cellphys::cli {

int kernel_demo_main(int argc, char** argv) {
  Integrator integ = Integrator::implicit_split;
  int steps = 600;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "-h" || a == "--help") return usage(stdout);
    if (a == "--integrator" && i + 1 < argc) {
      if (!parse_integrator(argv[++i], &integ)) {
        std::fprintf(stderr, "cellphys: unknown integrator '%s'\n", argv[i]);
        return usage(stderr);
      }
    } else if (a == "--steps" && i + 1 < argc) {
      steps = std::atoi(argv[++i]);
      if (steps <= 0) {
        std::fprintf(stderr, "cellphys: --steps must be a positive integer\n");
        return 2;
      }
    } else {
      std::fprintf(stderr, "cellphys: unknown argument '%s'\n", a.c_str());
      return usage(stderr);
    }
  }
  return demo(integ, steps);
}

}  // namespace cellphys::cli
