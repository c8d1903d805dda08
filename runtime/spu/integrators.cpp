#include "runtime/spu/integrators.h"

#include <algorithm>
#include <cmath>
#include <cstring>

#include "cellphys/gen/block_ops.h"
#include "runtime/spu/assembly.h"
#include "runtime/spu/rigid_motion.h"

namespace cellphys::spu {

using namespace cellphys::gen;

namespace {

constexpr uint32_t kGyroscopicBit = 1u << static_cast<uint32_t>(ForceType::gyroscopic);
// The forces are linearised at the step's start pose. A step that turns a body by more than
// this much more than its spin already did (rad) has left the region where that holds: a light
// body squeezed under heavy, load-stiffened contacts was spun up and thrown in one 60 Hz step
// (the mixed-pile contact test). Such a step is refused and halved, as a failed solve is.
constexpr double kMaxAddedTurn = 0.5;

Vec3d lin(const float* v8) { return Vec3d::load(v8); }
Vec3d ang(const float* v8) { return Vec3d::load(v8 + 4); }
bool finite8(const float* v8) {
  for (int k = 0; k < 8; ++k)
    if (!std::isfinite(v8[k])) return false;
  return true;
}
void zero_floats(float* p, size_t n) { std::memset(p, 0, n * sizeof(float)); }

void velocities(const IslandView& v, float* u) {
  for (int i = 0; i < v.num_bodies(); ++i) {
    const Rigid_Body& b = v.bodies[i];
    float* ui = u + kVecFloats * i;
    store3(ui, Vec3d::load(b.velocity));
    store3(ui + 4, Vec3d::load(b.angular_velocity));
  }
}

// saved state: position(4) orientation(4) velocity(4) angular_velocity(4)
void save_state(const IslandView& v, float* s) {
  for (int i = 0; i < v.num_bodies(); ++i) {
    const Rigid_Body& b = v.bodies[i];
    std::memcpy(s + 16 * i, b.position, 16);
    std::memcpy(s + 16 * i + 4, b.orientation, 16);
    std::memcpy(s + 16 * i + 8, b.velocity, 16);
    std::memcpy(s + 16 * i + 12, b.angular_velocity, 16);
  }
}
void restore_state(const IslandView& v, const float* s) {
  for (int i = 0; i < v.num_bodies(); ++i) {
    Rigid_Body& b = v.bodies[i];
    std::memcpy(b.position, s + 16 * i, 16);
    std::memcpy(b.orientation, s + 16 * i + 4, 16);
    std::memcpy(b.velocity, s + 16 * i + 8, 16);
    std::memcpy(b.angular_velocity, s + 16 * i + 12, 16);
  }
}

// Sets body i to the saved state moved by (dx, dtheta) and with velocity u (padded 8).
void set_stage(Rigid_Body& b, const float* saved, const Vec3d& dx, const Vec3d& dth, const float* u) {
  const Quatd q0 = Quatd::load(saved + 4);
  store3(b.position, Vec3d::load(saved) + dx);
  set_orientation(b, quat_mul(quat_exp(dth), q0));
  store3(b.velocity, lin(u));
  store3(b.angular_velocity, ang(u));
}

// a = W F for every body, in place (padded vectors), at the bodies' current orientations.
void accelerations(const IslandView& v, float* f) {
  for (int i = 0; i < v.num_bodies(); ++i) {
    const Rigid_Body& b = v.bodies[i];
    float* fi = f + kVecFloats * i;
    const Mat3d Iinv = rotate_sym(quat_to_matrix(orientation(b)), b.inverse_inertia_body);
    store3(fi, lin(fi) * double(b.inverse_mass));
    store3(fi + 4, mul(Iinv, ang(fi)));
  }
}

// The targets of the implicit system at the bodies' current state with step tau, zeroed:
// the half of assembly before the forces are evaluated.
ForceTargets implicit_targets(StepContext& c, float tau, uint32_t skip) {
  Workspace& ws = *c.ws;
  const IslandView& v = c.island;
  const int n = ws.n;
  compute_ws(v.bodies, n, ws.w);
  velocities(v, ws.u0);
  zero_floats(ws.forces, size_t(n) * kVecFloats);
  zero_floats(ws.diag, size_t(n) * kBlockFloats);
  zero_floats(ws.blocks, size_t(ws.structure.nnz) * kBlockFloats);
  ForceTargets t;
  t.forces = ws.forces;
  t.diag_k = ws.diag;
  t.offdiag_k = ws.blocks;
  t.structure = &ws.structure;
  t.h = tau;
  t.skip_types = skip;
  t.ref = ws.ref;
  return t;
}

// Assembles and scales the implicit system at the bodies' current state with step tau.
bool assemble(StepContext& c, float tau, uint32_t skip, float* p_out) {
  Workspace& ws = *c.ws;
  const ForceTargets t = implicit_targets(c, tau, skip);
  evaluate_forces(c.island, t, ws.force_scratch);
  return scale_system(ws.structure, ws.w, tau, ws.diag, ws.blocks, ws.forces, p_out);
}

// A system with no off-diagonal block (bodies that touch only the world, however many share
// the image) is solved a body at a time, each as the one-body system it is: a body's bits are
// then the ones it gets packed alone, whatever else shares its image (one solve of the whole
// would converge on the norms of all of them together).
SolveResult solve_each_body(StepContext& c, const BlockRowMatrix& A, const float* rhs, float* x) {
  SolveResult r;
  for (int i = 0; i < A.n; ++i) {
    BlockRowMatrix one = A;
    one.n = 1;
    one.row_start = A.row_start + i;
    const SolveResult ri = solve(c.solver, one, rhs + kVecFloats * i, x + kVecFloats * i, c.ws->solver_work, c.solve);
    r.iterations += ri.iterations;
    c.counters.solves += 1;
    r.residual = std::max(r.residual, ri.residual);
    if (ri.code != kConverged) {
      r.code = ri.code;
      break;
    }
  }
  return r;
}

bool run_solve(StepContext& c, const float* rhs, float* x) {
  zero_floats(x, size_t(c.ws->n) * kVecFloats);
  const BlockRowMatrix A = matrix_of(c.ws->structure, c.ws->blocks);
  SolveResult r;
  if (A.n > 1 && A.row_start[A.n] == 0) {
    r = solve_each_body(c, A, rhs, x);
  } else {
    r = solve(c.solver, A, rhs, x, c.ws->solver_work, c.solve);
    c.counters.solves += 1;
  }
  c.counters.solver_iterations += r.iterations;
  if (r.code != kConverged) {
    c.counters.last_solver_code = r.code;
    return false;
  }
  for (int i = 0; i < c.ws->n; ++i)
    if (!finite8(x + kVecFloats * i)) {
      c.counters.last_solver_code = kNotFinite;
      return false;
    }
  return true;
}

}  // namespace

bool prepare(StepContext& c) {
  Workspace& ws = *c.ws;
  for (int i = 0; i < ws.n; ++i) {  // the pose the island's contact geometry was measured at
    const Rigid_Body& b = c.island.bodies[i];
    float* r = ws.ref + kVecFloats * i;
    std::memcpy(r, b.position, 12);
    r[3] = 0.0f;
    std::memcpy(r + 4, b.orientation, 16);
  }
  if (!ws.structure.row_start) return true;
  return build_structure(c.island, ws.structure, ws.pair_scratch, ws.pair_capacity);
}

ForceTargets implicit_step_targets(StepContext& c, float h, bool split) {
  return implicit_targets(c, h, split ? kGyroscopicBit : 0u);
}

bool step_implicit(StepContext& c, float h, bool split) {
  const ForceTargets t = implicit_step_targets(c, h, split);
  evaluate_forces(c.island, t, c.ws->force_scratch);
  return finish_implicit(c, h, split);
}

void KickRotations::add(StepContext& c, int i, float h, bool split, bool* failed) {
  const Rigid_Body& b = c.island.bodies[i];
  const Vec3d w_kick = Vec3d::load(b.angular_velocity) + ang(c.ws->x + kVecFloats * i);
  // the kick changes angular momentum; the drift conserves it exactly
  if (split && !(b.flags & kBodyTurnsByKick)) {
    if (n_ > 0 && h != h_) flush();
    h_ = h;
    items_[n_] = {&c, i, failed};
    bodies_[n_] = &b;
    w_kick_[n_] = w_kick;
    if (++n_ == kLanes) flush();
    return;
  }
  put(c, i, h, advance_orientation(orientation(b), w_kick, h), w_kick, failed);
}

void KickRotations::flush() {
  if (n_ == 0) return;
  Quatd q1[kLanes];
  Vec3d w1[kLanes];
  bool ok[kLanes];
  kicked_free_rotations(bodies_, w_kick_, n_, h_, q1, w1, ok);
  for (int l = 0; l < n_; ++l) {
    if (ok[l]) put(*items_[l].c, items_[l].body, h_, q1[l], w1[l], items_[l].failed);
    else *items_[l].failed = true;
  }
  n_ = 0;
}

void KickRotations::put(StepContext& c, int i, float h, const Quatd& q1, const Vec3d& w1, bool* failed) {
  const Rigid_Body& b = c.island.bodies[i];
  if (h * (norm(w1) - norm(Vec3d::load(b.angular_velocity))) > kMaxAddedTurn) {
    *failed = true;
    return;
  }
  float* tmp = c.ws->u0 + kVecFloats * i;
  tmp[0] = float(q1.w), tmp[1] = float(q1.x), tmp[2] = float(q1.y), tmp[3] = float(q1.z);
  tmp[4] = float(w1.x), tmp[5] = float(w1.y), tmp[6] = float(w1.z), tmp[7] = 0.0f;
  if (!finite8(tmp)) *failed = true;
}

void add_kick_rotations(StepContext& c, KickRotations& rotations, float h, bool split, bool* failed) {
  for (int i = 0; i < c.ws->n; ++i) rotations.add(c, i, h, split, failed);
}

void commit_step(StepContext& c, float h) {
  Workspace& ws = *c.ws;
  for (int i = 0; i < ws.n; ++i) {
    Rigid_Body& b = c.island.bodies[i];
    const float* du = ws.x + kVecFloats * i;
    const float* tmp = ws.u0 + kVecFloats * i;
    for (int k = 0; k < 3; ++k) {
      b.velocity[k] += du[k];
      b.position[k] += h * b.velocity[k];
      b.angular_velocity[k] = tmp[4 + k];
    }
    std::memcpy(b.orientation, tmp, 16);
  }
}

namespace {

// The solve for the step's velocity change, then the new state committed (or nothing written):
// every body's new rotation into u0 (free now), failing before anything is written, then the commit.
bool solve_and_commit(StepContext& c, float h, bool split) {
  if (!run_solve(c, c.ws->forces, c.ws->x)) return false;
  KickRotations rotations;
  bool failed = false;
  add_kick_rotations(c, rotations, h, split, &failed);
  rotations.flush();
  if (failed) return false;
  commit_step(c, h);
  return true;
}

}  // namespace

bool finish_implicit(StepContext& c, float h, bool split) {
  Workspace& ws = *c.ws;
  if (!scale_system(ws.structure, ws.w, h, ws.diag, ws.blocks, ws.forces, nullptr, c.solve.sharer)) return false;
  return solve_and_commit(c, h, split);
}

void add_implicit_diagonal(StepContext& c, BlockInverter& inverter, bool* failed) {
  Workspace& ws = *c.ws;
  form_diagonal(ws.n, ws.w, ws.diag);
  for (int i = 0; i < ws.n; ++i) inverter.add(ws.diag + kBlockFloats * i, failed);
}

bool solve_inverted(StepContext& c, float h) {
  Workspace& ws = *c.ws;
  scale_inverted(ws.structure, ws.w, h, ws.diag, ws.blocks, ws.forces, nullptr);
  return run_solve(c, ws.forces, ws.x);
}

bool step_explicit(StepContext& c, float h, bool symplectic) {
  Workspace& ws = *c.ws;
  const IslandView& v = c.island;
  zero_floats(ws.forces, size_t(ws.n) * kVecFloats);
  ForceTargets t;
  t.h = h;  // the step the descriptors' h means
  t.forces = ws.forces;
  t.ref = ws.ref;
  evaluate_forces(v, t, ws.force_scratch);
  accelerations(v, ws.forces);
  for (int i = 0; i < ws.n; ++i)
    if (!finite8(ws.forces + kVecFloats * i)) return false;
  for (int i = 0; i < ws.n; ++i) {
    Rigid_Body& b = v.bodies[i];
    const float* a = ws.forces + kVecFloats * i;
    const Vec3d v0 = Vec3d::load(b.velocity), w0 = Vec3d::load(b.angular_velocity);
    const Vec3d v1 = {v0.x + h * a[0], v0.y + h * a[1], v0.z + h * a[2]};
    const Vec3d w1 = {w0.x + h * a[4], w0.y + h * a[5], w0.z + h * a[6]};
    const Vec3d& vx = symplectic ? v1 : v0;
    const Vec3d& wq = symplectic ? w1 : w0;
    store3(b.position, Vec3d::load(b.position) + vx * h);
    set_orientation(b, advance_orientation(orientation(b), wq, h));
    store3(b.velocity, v1);
    store3(b.angular_velocity, w1);
  }
  return true;
}

bool step_rk4(StepContext& c, float h) {
  // Classic RK4 on (x, q, u) with q in R^4 (q' = 1/2 (0, w) q) and normalised at the end;
  // stage forces see the normalised orientation.
  Workspace& ws = *c.ws;
  const IslandView& v = c.island;
  const int n = ws.n;
  save_state(v, ws.saved);
  zero_floats(ws.acc, size_t(n) * 16);
  static constexpr double kC[4] = {0.0, 0.5, 0.5, 1.0};
  static constexpr double kW[4] = {1.0 / 6, 2.0 / 6, 2.0 / 6, 1.0 / 6};
  // ws.k1 holds the previous stage's (a) per body; stage velocities come from the bodies
  for (int s = 0; s < 4; ++s) {
    if (s > 0) {
      // y_s = y0 + c_s h k_{s-1}; k_{s-1} = (v, q', a) of the stage just evaluated, kept in acc's scratch
      for (int i = 0; i < n; ++i) {
        const float* y0 = ws.saved + 16 * i;
        const float* kp = ws.k1 + kVecFloats * i;  // previous a
        Rigid_Body& b = v.bodies[i];
        const double ch = kC[s] * h;
        // previous stage velocities were left in the body (set below)
        const Vec3d vs = Vec3d::load(b.velocity), ws_ = Vec3d::load(b.angular_velocity);
        const Quatd qs = orientation(b);
        // q'_{s-1} = 1/2 (0, w_{s-1}) q_{s-1} with the unnormalised stage q kept in y? use the body's
        const Quatd dq = quat_mul({0.0, ws_.x, ws_.y, ws_.z}, qs);
        store3(b.position, Vec3d::load(y0) + vs * ch);
        const Quatd q{y0[4] + ch * 0.5 * dq.w, y0[5] + ch * 0.5 * dq.x, y0[6] + ch * 0.5 * dq.y, y0[7] + ch * 0.5 * dq.z};
        set_orientation(b, q);
        store3(b.velocity, Vec3d::load(y0 + 8) + lin(kp) * ch);
        store3(b.angular_velocity, Vec3d::load(y0 + 12) + ang(kp) * ch);
      }
    }
    zero_floats(ws.k1, size_t(n) * kVecFloats);
    ForceTargets t;
    t.h = h;  // the step the descriptors' h means
    t.forces = ws.k1;
    t.ref = ws.ref;
    evaluate_forces(v, t, ws.force_scratch);
    accelerations(v, ws.k1);
    for (int i = 0; i < n; ++i) {
      const Rigid_Body& b = v.bodies[i];
      const float* a = ws.k1 + kVecFloats * i;
      if (!finite8(a)) {
        restore_state(v, ws.saved);
        return false;
      }
      const Vec3d vs = Vec3d::load(b.velocity), wsv = Vec3d::load(b.angular_velocity);
      const Quatd dq = quat_mul({0.0, wsv.x, wsv.y, wsv.z}, orientation(b));
      float* acc = ws.acc + 16 * i;
      const double wgt = kW[s];
      acc[0] += float(wgt * vs.x), acc[1] += float(wgt * vs.y), acc[2] += float(wgt * vs.z);
      acc[4] += float(wgt * 0.5 * dq.w), acc[5] += float(wgt * 0.5 * dq.x);
      acc[6] += float(wgt * 0.5 * dq.y), acc[7] += float(wgt * 0.5 * dq.z);
      acc[8] += float(wgt * a[0]), acc[9] += float(wgt * a[1]), acc[10] += float(wgt * a[2]);
      acc[12] += float(wgt * a[4]), acc[13] += float(wgt * a[5]), acc[14] += float(wgt * a[6]);
    }
  }
  for (int i = 0; i < n; ++i) {
    const float* y0 = ws.saved + 16 * i;
    const float* acc = ws.acc + 16 * i;
    Rigid_Body& b = v.bodies[i];
    store3(b.position, Vec3d::load(y0) + lin(acc) * h);
    set_orientation(b, {y0[4] + h * double(acc[4]), y0[5] + h * double(acc[5]), y0[6] + h * double(acc[6]),
                        y0[7] + h * double(acc[7])});
    store3(b.velocity, Vec3d::load(y0 + 8) + Vec3d::load(acc + 8) * h);
    store3(b.angular_velocity, Vec3d::load(y0 + 12) + Vec3d::load(acc + 12) * h);
  }
  return true;
}

bool step_rosenbrock(StepContext& c, float h, float* error) {
  // ROS2 (Verwer et al. 1999), gamma = 1 + 1/sqrt(2), on y = (pose, u) with the Jacobian
  // J = [[0, I], [W dF/ddelta, W dF/du]]. Both stages solve with the same matrix
  // A(tau) = I - tau W dF/du - tau^2 W dF/ddelta, tau = gamma h: the implicit Euler matrix.
  Workspace& ws = *c.ws;
  const IslandView& v = c.island;
  const int n = ws.n;
  const double gamma = 1.0 + 1.0 / std::sqrt(2.0);
  const float tau = float(gamma * h);
  save_state(v, ws.saved);
  auto fail = [&]() {
    restore_state(v, ws.saved);
    return false;
  };
  // Stage 1: A(tau) ku1 = W F + tau W dF/ddelta u0; the assembled b̂ is tau times that.
  if (!assemble(c, tau, 0u, ws.p)) return fail();
  if (!run_solve(c, ws.forces, ws.x)) return fail();
  for (int k = 0; k < n * kVecFloats; ++k) ws.k1[k] = ws.x[k] / tau;  // ku1
  // Stage 2 force at y0 + h k1: pose moved by h kdelta1 = h (u0 + tau ku1), velocity u0 + h ku1.
  for (int i = 0; i < n; ++i) {
    const float* u0 = ws.u0 + kVecFloats * i;
    const float* k1 = ws.k1 + kVecFloats * i;
    alignas(32) float us[kVecFloats], kd[kVecFloats];
    for (int r = 0; r < kVecFloats; ++r) {
      kd[r] = u0[r] + tau * k1[r];
      us[r] = u0[r] + h * k1[r];
    }
    set_stage(v.bodies[i], ws.saved + 16 * i, lin(kd) * h, ang(kd) * h, us);
  }
  zero_floats(ws.jv, size_t(n) * kVecFloats);
  {
    ForceTargets t;
    t.h = tau;  // the step the descriptors' h means
    t.forces = ws.jv;
    t.ref = ws.ref;
    evaluate_forces(v, t, ws.force_scratch);
  }
  // g2 = M0 W_s F_s - 2 M0 ku1 + tau dF/ddelta(y0) fdelta2, fdelta2 = -u0 + (h - 2 tau) ku1,
  // in force units so that b̂2 = P g2 (P = D^-1 W0).
  accelerations(v, ws.jv);  // W_s F_s at the stage orientation
  restore_state(v, ws.saved);
  for (int i = 0; i < n; ++i) {
    const Rigid_Body& b = v.bodies[i];
    float* a = ws.jv + kVecFloats * i;
    const float* k1 = ws.k1 + kVecFloats * i;
    const Mat3d I0 = rotate_sym(quat_to_matrix(orientation(b)), b.inertia_body);
    const Vec3d ar = mul(I0, ang(a) - ang(k1) * 2.0);
    const double m = b.mass;
    store3(a, (lin(a) - lin(k1) * 2.0) * m);
    store3(a + 4, ar);
    // fdelta2 into forces (free now) for the Jacobian product
    const float* u0 = ws.u0 + kVecFloats * i;
    float* fd = ws.forces + kVecFloats * i;
    for (int r = 0; r < kVecFloats; ++r) fd[r] = -u0[r] + (h - 2.0f * tau) * k1[r];
  }
  {
    // jv += tau dF/ddelta(y0) fdelta2: the kernels at y0 again, Jacobian product only
    zero_floats(ws.x, size_t(n) * kVecFloats);  // discard F from this pass
    ForceTargets t;
    t.h = tau;  // the step the descriptors' h means
    t.forces = ws.x;
    t.jv_in = ws.forces;
    t.ref = ws.ref;
    t.jv_out = ws.diag;  // scratch
    zero_floats(ws.diag, size_t(n) * kVecFloats);
    evaluate_forces(v, t, ws.force_scratch);
    for (int k = 0; k < n * kVecFloats; ++k) ws.jv[k] += tau * ws.diag[k];
  }
  scale_rhs(n, ws.p, ws.jv, ws.forces);
  if (!run_solve(c, ws.forces, ws.x)) return fail();  // ku2
  // Error estimate e = h/2 (k1 + k2), filtered as (I - tau J)^-1 e (Shampine): the raw
  // estimate does not vanish for stiff modes (contacts) the L-stable step damps correctly.
  // Same reduction as the stages: A e_u' = e_u + tau W dF/ddelta e_delta, e_delta' = e_delta + tau e_u'.
  auto raw_error = [&](int i, float* e_pose, float* e_vel) {
    const float* u0 = ws.u0 + kVecFloats * i;
    const float* k1 = ws.k1 + kVecFloats * i;
    const float* k2 = ws.x + kVecFloats * i;
    for (int r = 0; r < kVecFloats; ++r) {
      const float kd1 = u0[r] + tau * k1[r], kd2 = -u0[r] + (h - 2.0f * tau) * k1[r] + tau * k2[r];
      e_pose[r] = 0.5f * h * (kd1 + kd2);
      e_vel[r] = 0.5f * h * (k1[r] + k2[r]);
    }
  };
  for (int i = 0; i < n; ++i) {
    alignas(32) float ev[kVecFloats];
    raw_error(i, ws.jv + kVecFloats * i, ev);
  }
  float* jv_out = ws.diag;
  float* dump = ws.diag + size_t(n) * kVecFloats;
  zero_floats(jv_out, size_t(n) * kVecFloats);
  zero_floats(dump, size_t(n) * kVecFloats);
  {
    ForceTargets t;
    t.h = tau;  // the step the descriptors' h means
    t.forces = dump;
    t.jv_in = ws.jv;
    t.jv_out = jv_out;
    t.ref = ws.ref;
    evaluate_forces(v, t, ws.force_scratch);
  }
  for (int i = 0; i < n; ++i) {  // g = M0 e_u + tau dF/ddelta e_delta, force units
    const Rigid_Body& b = v.bodies[i];
    alignas(32) float ep[kVecFloats], ev[kVecFloats];
    raw_error(i, ep, ev);
    const float* jd = jv_out + kVecFloats * i;
    const Mat3d I0 = rotate_sym(quat_to_matrix(orientation(b)), b.inertia_body);
    const Vec3d Ir = mul(I0, ang(ev));
    float* g = ws.forces + kVecFloats * i;
    store3(g, {b.mass * double(ev[0]) + tau * jd[0], b.mass * double(ev[1]) + tau * jd[1], b.mass * double(ev[2]) + tau * jd[2]});
    store3(g + 4, {Ir.x + tau * jd[4], Ir.y + tau * jd[5], Ir.z + tau * jd[6]});
  }
  scale_rhs(n, ws.p, ws.forces, ws.jv);
  if (!run_solve(c, ws.jv, ws.forces)) return fail();  // filtered e_u
  double err2 = 0.0;
  for (int i = 0; i < n; ++i) {
    const float* u0 = ws.u0 + kVecFloats * i;
    const float* k1 = ws.k1 + kVecFloats * i;
    const float* k2 = ws.x + kVecFloats * i;
    const float* y0 = ws.saved + 16 * i;
    const float* euf = ws.forces + kVecFloats * i;
    alignas(32) float ep[kVecFloats], ev[kVecFloats], kd1[kVecFloats], kd2[kVecFloats];
    raw_error(i, ep, ev);
    for (int r = 0; r < kVecFloats; ++r) {
      kd1[r] = u0[r] + tau * k1[r];
      kd2[r] = -u0[r] + (h - 2.0f * tau) * k1[r] + tau * k2[r];
    }
    for (int r : {0, 1, 2, 4, 5, 6}) {
      const double e_pose = double(ep[r]) + tau * double(euf[r]);
      const double e_vel = euf[r];
      const double pose_scale = 1.0 + (r < 3 ? std::fabs(y0[r]) : 0.0);
      const double vel_scale = 1.0 + std::fabs(double(u0[r]));
      err2 += (e_pose / pose_scale) * (e_pose / pose_scale) + (e_vel / vel_scale) * (e_vel / vel_scale);
    }
    // y1 = y0 + h (3/2 k1 + 1/2 k2)
    alignas(32) float unew[kVecFloats];
    for (int r = 0; r < kVecFloats; ++r) unew[r] = u0[r] + h * (1.5f * k1[r] + 0.5f * k2[r]);
    if (!finite8(unew)) return fail();
    const Vec3d dx = (lin(kd1) * 1.5 + lin(kd2) * 0.5) * h;
    const Vec3d dth = (ang(kd1) * 1.5 + ang(kd2) * 0.5) * h;
    set_stage(v.bodies[i], y0, dx, dth, unew);
  }
  *error = float(std::sqrt(err2 / (6.0 * n)) / c.error_tolerance);
  if (!std::isfinite(*error)) return fail();
  if (*error > 1.0f) {
    c.counters.rejected += 1;
    return fail();
  }
  return true;
}

}  // namespace cellphys::spu
