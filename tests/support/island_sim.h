// Test helpers shared by the compute-kernel tests (header-only): build one island from a list
// of bodies and a force callback, step it on a ComputeWorker, read the result back, and
// integrate many steps by rebuilding the island from the advanced bodies (the kernel is
// stateless). Also the closed-form quantities the tests compare against (energy, angular
// momentum) computed in double from the packed state.
#pragma once
#include <cmath>
#include <cstdint>
#include <cstring>
#include <functional>
#include <memory>
#include <vector>

#include "cellphys/gen/layouts.h"
#include "runtime/spu/island_image.h"
#include "runtime/spu/kernel.h"
#include "runtime/base/quat.h"

namespace cellphys::test_support {

using gen::Rigid_Body;
using gen::Rigid_Body_Fields;
using gen::Rigid_Body_Step;
using spu::Integrator;

/// A box of half-extents (hx, hy, hz) and mass m at the origin, identity orientation, at rest.
inline Rigid_Body_Fields make_box(double m, double hx, double hy, double hz) {
  Rigid_Body_Fields b;
  b.orientation[0] = 1.0f;
  b.mass = float(m);
  b.inverse_mass = float(1.0 / m);
  const double I[3] = {m / 3 * (hy * hy + hz * hz), m / 3 * (hx * hx + hz * hz), m / 3 * (hx * hx + hy * hy)};
  for (int k = 0; k < 3; ++k) {
    b.inertia_body[k] = float(I[k]);
    b.inverse_inertia_body[k] = float(1.0 / I[k]);
  }
  b.friction = 0.5f;
  b.scale = 1.0f;
  return b;
}

/// How one island is stepped.
struct StepSettings {
  Integrator integrator = Integrator::implicit_split;
  double h = 1.0 / 60.0;
  float tolerance = 1e-5f;
  uint32_t solver = 0;  // 0 cgs, 1 bicgstab, 2 direct
  uint32_t max_halvings = 8;
};

/// Byte offsets inside a kernel result of n bodies.
inline size_t result_steps_offset() { return spu::align16(sizeof(gen::Island_Result)); }
inline size_t result_bodies_offset(int n) { return result_steps_offset() + size_t(n) * sizeof(Rigid_Body_Step); }

inline gen::Island_Result result_header(const std::vector<unsigned char>& res) {
  gen::Island_Result h;
  std::memcpy(static_cast<void*>(&h), res.data(), sizeof h);
  return h;
}
inline Rigid_Body_Step result_step(const std::vector<unsigned char>& res, int n, int i) {
  Rigid_Body_Step s;
  std::memcpy(static_cast<void*>(&s), res.data() + result_steps_offset() + size_t(i) * sizeof s, sizeof s);
  (void)n;
  return s;
}
inline Rigid_Body result_body(const std::vector<unsigned char>& res, int n, int i) {
  Rigid_Body b;
  std::memcpy(static_cast<void*>(&b), res.data() + result_bodies_offset(n) + size_t(i) * sizeof b, sizeof b);
  return b;
}

/// The packed bodies of an image (what the result of a failed step must carry back).
inline const unsigned char* image_bodies(const std::vector<unsigned char>& img) {
  const gen::Island_Header* h = reinterpret_cast<const gen::Island_Header*>(img.data());
  return img.data() + spu::island_layout(h->num_bodies, h->num_sections).bodies;
}

/// A set of bodies and the forces between them, stepped one island per step.
struct Sim {
  std::vector<Rigid_Body_Fields> bodies;
  /// Adds the forces (and globals, params) to a builder that already holds the bodies.
  std::function<void(spu::IslandBuilder&)> forces;
  StepSettings settings;
  std::shared_ptr<spu::ComputeWorker> worker = std::make_shared<spu::ComputeWorker>();
  spu::IslandReport last;
  std::vector<unsigned char> result;
  double time = 0.0;
  int failures = 0;

  std::vector<unsigned char> image() const {
    spu::IslandBuilder ib;
    ib.set_integrator(settings.integrator);
    ib.set_step(float(settings.h));
    ib.set_tolerance(settings.tolerance);
    ib.set_solver(settings.solver);
    ib.set_max_halvings(settings.max_halvings);
    for (const auto& b : bodies) ib.add_body(b);
    if (forces) forces(ib);
    return ib.finish();
  }

  /// One kernel step; on success the bodies advance. Returns whether the kernel said ok.
  bool step() {
    const auto img = image();
    const int n = int(bodies.size());
    result.assign(spu::result_bytes(uint32_t(n)), 0);
    last = worker->step(img.data(), img.size(), result.data(), result.size());
    if (last.status != spu::IslandStatus::ok) {
      ++failures;
      return false;
    }
    for (int i = 0; i < n; ++i) gen::unpack(result_body(result, n, i), bodies[i]);
    time += settings.h;
    return true;
  }

  /// Runs `steps` steps, calling `each(step_index)` after every successful one; stops at
  /// the first failure and returns the number of successful steps.
  int run(int steps, const std::function<void(int)>& each = nullptr) {
    for (int s = 0; s < steps; ++s) {
      if (!step()) return s;
      if (each) each(s);
    }
    return steps;
  }
};

// ---- closed-form quantities, in double from the float state ----

/// World angular momentum L = R I_body R^T omega.
inline Vec3d angular_momentum(const Rigid_Body_Fields& b) {
  const Mat3d R = quat_to_matrix(quat_normalized(Quatd::load(b.orientation)));
  return mul(rotate_sym(R, b.inertia_body), Vec3d::load(b.angular_velocity));
}

/// Rotational kinetic energy 1/2 omega . L.
inline double rotational_energy(const Rigid_Body_Fields& b) {
  return 0.5 * dot(Vec3d::load(b.angular_velocity), angular_momentum(b));
}

/// Translational kinetic energy.
inline double linear_energy(const Rigid_Body_Fields& b) {
  const Vec3d v = Vec3d::load(b.velocity);
  return 0.5 * double(b.mass) * dot(v, v);
}

/// World position of a body-frame point.
inline Vec3d world_point(const Rigid_Body_Fields& b, const float* local) {
  const Mat3d R = quat_to_matrix(quat_normalized(Quatd::load(b.orientation)));
  const Vec3d r = mul(R, Vec3d::load(local));
  return Vec3d::load(b.position) + r;
}

inline bool finite_body(const Rigid_Body_Fields& b) {
  for (int k = 0; k < 3; ++k)
    if (!std::isfinite(b.position[k]) || !std::isfinite(b.velocity[k]) || !std::isfinite(b.angular_velocity[k]))
      return false;
  for (int k = 0; k < 4; ++k)
    if (!std::isfinite(b.orientation[k])) return false;
  return true;
}

}  // namespace cellphys::test_support
