// Tests of the generated force kernels (generated/cellphys/gen/forces/*.h): Jacobian blocks
// against central finite differences of F, F against an independent Eigen evaluation, the
// implicit form against F and the blocks, SIMD batches against scalar float, the contact clamps.
//
// Kernels are reached through visit_kernels() and their inputs are discovered by probing
// gather() with sentinel values, so a force added by descriptor is covered without editing
// this file -- except the hand reference of F, which is deliberately written per force.
//
// Built with CELLPHYS_TESTED_FORCES defined (a comma-separated list of force names), only those
// forces' kernels are instantiated and checked: a force set that adds descriptors to the
// production set (examples/new_force) checks what it adds, the production kernels being this
// test's in the main build (each kernel costs minutes of compiling on the scalar path).
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdio>
#include <cstdint>
#include <cstring>
#include <limits>
#include <map>
#include <random>
#include <string>
#include <vector>

#include "cellphys/gen/force_table.h"

namespace {

namespace g = cellphys::gen;
using cellphys::simd::Batch;
using Vec3 = Eigen::Vector3d;
using Mat3 = Eigen::Matrix3d;
using Mat6 = Eigen::Matrix<double, 6, 6>;
using Quat = Eigen::Quaterniond;

// ---- A force instance and its state in double, word by word -------------------------------

constexpr int kBodyWords = sizeof(g::Rigid_Body) / 4;
constexpr int kGlobalWords = sizeof(g::Island_Params) / 4;
constexpr int kPos = offsetof(g::Rigid_Body, position) / 4;
constexpr int kQuat = offsetof(g::Rigid_Body, orientation) / 4;
constexpr int kVel = offsetof(g::Rigid_Body, velocity) / 4;
constexpr int kAngVel = offsetof(g::Rigid_Body, angular_velocity) / 4;
constexpr int kInertia = offsetof(g::Rigid_Body, inertia_body) / 4;
constexpr int kInvInertia = offsetof(g::Rigid_Body, inverse_inertia_body) / 4;
constexpr int kMass = offsetof(g::Rigid_Body, mass) / 4;
constexpr int kInvMass = offsetof(g::Rigid_Body, inverse_mass) / 4;

enum Region { kBodyA = 0, kBodyB = 1, kInstance = 2, kGlobals = 3, kRef = 4, kNumRegions = 5 };
constexpr int kRefWords = 8;  // gather's `ref`: per body the reference pose x y z _ w x y z
// The step the kernels are evaluated for (a descriptor's `h`: a contact closing within it acts).
constexpr double kEvalH = 1.0 / 60.0;
constexpr double kPi = 3.14159265358979323846;

// One double per 4-byte word of the packed bodies, instance, Island_Params and reference poses:
// FD perturbs this in double, and float kernels see it rounded exactly as pack() + gather() would.
// The reference pose (where world-frame contact geometry was measured) stays pinned under FD.
template <class K>
struct Case {
  static constexpr int kInstWords = sizeof(typename K::Instance) / 4;
  double body[2][kBodyWords] = {};
  double inst[kInstWords] = {};
  double glob[kGlobalWords] = {};
  double ref[2 * kRefWords] = {};
  int words(int r) const {
    const int n[kNumRegions] = {kBodyWords, kBodyWords, kInstWords, kGlobalWords, 2 * kRefWords};
    return n[r];
  }
  double* region(int r) {
    double* p[kNumRegions] = {body[0], body[1], inst, glob, ref};
    return p[r];
  }
  const double* region(int r) const { return const_cast<Case*>(this)->region(r); }
};

const g::ForceInfo& info_of(g::ForceType t) {
  for (const auto& f : g::kForceTable) if (f.type == t) return f;
  ADD_FAILURE() << "force type " << static_cast<int>(t) << " missing from kForceTable";
  return g::kForceTable[0];
}

// Whether `name` is one of the comma-separated `list`.
constexpr bool in_list(const char* list, const char* name) {
  for (const char* p = list; *p;) {
    const char* q = name;
    while (*p && *p != ',' && *p == *q) { ++p; ++q; }
    if ((*p == ',' || *p == 0) && *q == 0) return true;
    while (*p && *p != ',') ++p;
    if (*p == ',') ++p;
  }
  return false;
}
template <class K> constexpr bool kTested = [] {
#ifdef CELLPHYS_TESTED_FORCES
  for (const auto& f : g::kForceTable)
    if (f.type == K::kType) return in_list(CELLPHYS_TESTED_FORCES, f.name);
  return false;
#else
  return true;
#endif
}();
// The kernels this build checks (all of them unless CELLPHYS_TESTED_FORCES names some).
template <class Fn>
void visit_tested_kernels(Fn&& fn) {
  g::visit_kernels([&](auto k) {
    if constexpr (kTested<decltype(k)>) fn(k);
  });
}
bool force_tested(const char* name) {
#ifdef CELLPHYS_TESTED_FORCES
  return in_list(CELLPHYS_TESTED_FORCES, name);
#else
  (void)name;
  return true;
#endif
}

template <class K> constexpr bool kPair = K::kVariant == g::KernelVariant::pair;

template <class K> std::string kernel_name() {
  const char* v[] = {"body", "pair", "world"};
  return std::string(info_of(K::kType).name) + "_" + v[static_cast<int>(K::kVariant)];
}

const g::ParamInfo* find_param(const g::ForceInfo& fi, const char* name) {
  for (uint32_t i = 0; i < fi.num_params; ++i)
    if (fi.params[i].lanes > 0 && std::strcmp(fi.params[i].name, name) == 0) return &fi.params[i];
  return nullptr;
}
template <class K> double* param(Case<K>& c, const char* name) {
  const g::ParamInfo* p = find_param(info_of(K::kType), name);
  return p ? c.inst + p->offset / 4 : nullptr;
}
template <class K> const double* param(const Case<K>& c, const char* name) {
  return param(const_cast<Case<K>&>(c), name);
}
template <class K> double* global_at(Case<K>& c, const char* name) {
  for (const auto& gi : g::kGlobalTable)
    if (std::strcmp(gi.param.name, name) == 0) return c.glob + gi.param.offset / 4;
  ADD_FAILURE() << "no global " << name;
  static double none = 0;
  return &none;
}
template <class K> double global(const Case<K>& c, const char* name) {
  return *global_at(const_cast<Case<K>&>(c), name);
}
// The contact point is a world point attached to both bodies at the start of the step.
template <class K> bool contact_like() {
  const auto& fi = info_of(K::kType);
  return find_param(fi, "point") && find_param(fi, "normal") && find_param(fi, "penetration");
}

Vec3 vec3_at(const double* p) { return {p[0], p[1], p[2]}; }
void set3(double* p, const Vec3& v) { p[0] = v.x(); p[1] = v.y(); p[2] = v.z(); }
Quat quat_at(const double* b) { return {b[kQuat], b[kQuat + 1], b[kQuat + 2], b[kQuat + 3]}; }
void set_quat(double* b, const Quat& q) {
  b[kQuat] = q.w(); b[kQuat + 1] = q.x(); b[kQuat + 2] = q.y(); b[kQuat + 3] = q.z();
}

struct BodyD {
  Vec3 x, v, w;
  Mat3 R, Iw;
  double m;
};
struct Pose { Vec3 x; Mat3 R; };
Pose ref_pose(const double* r) { return {vec3_at(r), Quat(r[4], r[5], r[6], r[7]).toRotationMatrix()}; }
BodyD body_of(const double* b) {
  const double* I = b + kInertia;  // Ixx Iyy Izz Ixy Ixz Iyz
  Mat3 Ib;
  Ib << I[0], I[3], I[4], I[3], I[1], I[5], I[4], I[5], I[2];
  BodyD d{vec3_at(b + kPos), vec3_at(b + kVel), vec3_at(b + kAngVel), quat_at(b).toRotationMatrix(), {}, b[kMass]};
  d.Iw = d.R * Ib * d.R.transpose();
  return d;
}

// ---- Packing and probing gather() ----------------------------------------------------------

template <class K>
struct Packed {
  g::Rigid_Body bodies[2];
  typename K::Instance inst;
  g::Island_Params glob;
  float ref[2 * kRefWords];
};

void store_words(void* dst, const double* src, int n) {
  for (int i = 0; i < n; ++i) {
    const float f = static_cast<float>(src[i]);
    std::memcpy(static_cast<unsigned char*>(dst) + 4 * i, &f, 4);
  }
}

template <class K>
Packed<K> pack(const Case<K>& c) {
  Packed<K> p;
  store_words(&p.bodies[0], c.body[0], kBodyWords);
  store_words(&p.bodies[1], c.body[1], kBodyWords);
  store_words(&p.inst, c.inst, Case<K>::kInstWords);
  store_words(&p.glob, c.glob, kGlobalWords);
  store_words(p.ref, c.ref, 2 * kRefWords);
  const auto& fi = info_of(K::kType);
  const int32_t a = 0, b = kPair<K> ? 1 : -1;  // world variants: b is the world
  std::memcpy(reinterpret_cast<unsigned char*>(&p.inst) + fi.offset_body_a, &a, 4);
  if (fi.offset_body_b >= 0) std::memcpy(reinterpret_cast<unsigned char*>(&p.inst) + fi.offset_body_b, &b, 4);
  return p;
}

template <class K>
void gather(const Packed<K>& p, float* in, bool with_ref = true, int stride = 1) {
  K::gather(p.bodies, p.inst, p.glob, in, with_ref ? p.ref : nullptr, stride);
}

struct Source { int region, word; };
struct Probe {
  ::testing::AssertionResult ok = ::testing::AssertionSuccess();
  std::vector<Source> src;  // input i is word src[i].word of region src[i].region
  bool reads_ref = false;
};

// Fills every word with a distinct integer sentinel (exact in float), gathers, and maps each
// input back to the word it came from; fails if an input matches no sentinel.
template <class K>
Probe run_probe() {
  const auto& fi = info_of(K::kType);
  Probe pr;
  Case<K> c;
  std::map<float, Source> owner;
  double next = 1000;
  for (int r = 0; r < kNumRegions; ++r)
    for (int w = 0; w < c.words(r); ++w) {
      if (r == kInstance && (4 * w == int(fi.offset_body_a) || 4 * w == fi.offset_body_b)) continue;
      c.region(r)[w] = next;
      owner[float(next)] = {r, w};
      next += 1;
    }
  const Packed<K> p = pack(c);
  std::vector<float> in(K::kInputs, std::numeric_limits<float>::quiet_NaN());
  gather(p, in.data());
  for (int i = 0; i < K::kInputs; ++i) {
    auto it = owner.find(in[i]);
    if (it == owner.end()) {
      pr.ok = ::testing::AssertionFailure() << "input " << i << " = " << in[i] << " reads no probed word";
      return pr;
    }
    const Source s = it->second;
    if ((s.region == kBodyB || (s.region == kRef && s.word >= kRefWords)) && !kPair<K>) {
      pr.ok = ::testing::AssertionFailure() << "input " << i << " reads body b in a one-body kernel";
      return pr;
    }
    pr.reads_ref |= s.region == kRef;
    pr.src.push_back(s);
  }
  return pr;
}

template <class K> const Probe& probe() {
  static const Probe p = run_probe<K>();
  return p;
}

template <class T, class K>
std::vector<T> inputs(const Case<K>& c) {
  const std::vector<Source>& src = probe<K>().src;
  std::vector<T> in(K::kInputs);
  for (int i = 0; i < K::kInputs; ++i) in[i] = T(c.region(src[i].region)[src[i].word]);
  return in;
}

template <class T, class K>
std::vector<T> eval_case(const Case<K>& c, double h = kEvalH) {
  std::vector<T> out(K::kOutputs);
  K::template eval<T>(inputs<T>(c).data(), T(h), out.data());
  return out;
}

// The lagged() values of a case: what the linearisation holds through the step.
template <class K>
std::vector<double> held_values(const Case<K>& c) {
  std::vector<double> held(K::kHeld > 0 ? K::kHeld : 1), f(6 * K::kBodies);
  K::template eval_f<double>(inputs<double>(c).data(), kEvalH, f.data(), nullptr, held.data());
  return held;
}

// F with the lagged values given (taken at another state).
template <class K>
std::vector<double> eval_f_held(const Case<K>& c, const std::vector<double>& held) {
  std::vector<double> f(6 * K::kBodies);
  K::template eval_f<double>(inputs<double>(c).data(), kEvalH, f.data(), held.data());
  return f;
}

// ---- Random states --------------------------------------------------------------------------

struct Rng {
  std::mt19937_64 gen;
  explicit Rng(uint64_t seed) : gen(seed) {}
  double uni(double lo, double hi) { return std::uniform_real_distribution<double>(lo, hi)(gen); }
  double gauss() { return std::normal_distribution<double>()(gen); }
  Vec3 vec(double lo, double hi) { return {uni(lo, hi), uni(lo, hi), uni(lo, hi)}; }
  Vec3 unit() { Vec3 v(gauss(), gauss(), gauss()); return v.norm() > 1e-6 ? v.normalized() : unit(); }
  Quat rotation() { Quat q(gauss(), gauss(), gauss(), gauss()); return q.norm() > 1e-6 ? q.normalized() : rotation(); }
};

// A rotated, moving body with off-diagonal inertia; `ref` gets its reference pose, which is
// the current pose or, half the time, where it was before a small rigid motion (a later stage).
void random_body(Rng& rng, double* b, double* ref) {
  const double m = rng.uni(0.5, 5);
  // SPD inertia, non-diagonal in body axes: principal moments within a factor 2 (so the
  // triangle inequality holds) in random principal axes Q.
  const Mat3 Q = rng.rotation().toRotationMatrix();
  const Vec3 d = m * rng.vec(0.05, 0.1);
  const Mat3 I = Q * d.asDiagonal() * Q.transpose(), Ii = I.inverse();
  Vec3 x = rng.vec(-1, 1);
  Quat q = rng.rotation();
  set3(ref, x);
  ref[4] = q.w(); ref[5] = q.x(); ref[6] = q.y(); ref[7] = q.z();
  if (rng.uni(0, 1) < 0.5) {
    x += rng.vec(-0.05, 0.05);
    q = (Quat(Eigen::AngleAxisd(rng.uni(0, 0.2), rng.unit())) * q).normalized();
  }
  set3(b + kPos, x);
  set_quat(b, q);
  set3(b + kVel, rng.vec(-1, 1));
  set3(b + kAngVel, rng.vec(-2, 2));
  const int sym[6][2] = {{0, 0}, {1, 1}, {2, 2}, {0, 1}, {0, 2}, {1, 2}};
  for (int k = 0; k < 6; ++k) {
    b[kInertia + k] = I(sym[k][0], sym[k][1]);
    b[kInvInertia + k] = Ii(sym[k][0], sym[k][1]);
  }
  b[kMass] = m;
  b[kInvMass] = 1 / m;
}

// World position of attachment param `name` (body frame; world frame on the world side).
template <class K> Vec3 attachment(const Case<K>& c, const char* name, int body) {
  const Vec3 r = vec3_at(param(c, name));
  if (body == 1 && !kPair<K>) return r;
  const BodyD B = body_of(c.body[body]);
  return B.x + B.R * r;
}

struct ContactRef { Vec3 pa, pb, f; double depth, held, vn, fall, k, c, slop, hold, rest; };
// The contact straight from the descriptor: pa, pb are the material points of a and b that were
// at `point` at the reference pose (the world's is `point` itself); depth = penetration - (pb - pa).n.
template <class K> ContactRef contact_ref(const Case<K>& c) {
  ContactRef r;
  const Vec3 p = vec3_at(param(c, "point")), n = vec3_at(param(c, "normal"));
  // Soft unless fixed: k = m w^2, c = 2 zeta m w at w = 2 pi hertz.
  // tuned to the larger of its effective mass and the load it carries
  const double mass = std::max(*param(c, "mass"), *param(c, "load")), omega = 2 * M_PI * global(c, "contact_hertz");
  const double k_fixed = global(c, "contact_stiffness"), c_fixed = global(c, "contact_damping");
  r.k = k_fixed > 0 ? k_fixed : mass * omega * omega;
  r.c = c_fixed > 0 ? c_fixed : 2 * global(c, "contact_damping_ratio") * mass * omega;
  r.slop = global(c, "contact_slop");
  r.hold = *param(c, "hold");
  r.rest = global(c, "contact_rest_speed");
  const double mu = *param(c, "friction"), slip = global(c, "slip_velocity");
  Vec3 vel[2];
  for (int body = 0; body < 2; ++body) {
    Vec3& at = body ? r.pb : r.pa;
    if (body == 1 && !kPair<K>) { at = p; vel[1].setZero(); continue; }
    const BodyD B = body_of(c.body[body]);
    const Pose ref = ref_pose(c.ref + kRefWords * body);
    const Vec3 off = B.R * ref.R.transpose() * (p - ref.x);
    at = B.x + off;
    vel[body] = B.v + B.w.cross(off);
  }
  const Vec3 moved = r.pb - r.pa;
  r.depth = *param(c, "penetration") - n.dot(moved);
  r.held = std::min(r.depth, r.hold);  // deeper overlap is pushed out, not sprung
  const Vec3 vrel = vel[1] - vel[0];
  r.vn = n.dot(vrel);
  r.fall = *param(c, "fall");
  // overlapping: pushes only; a gap that closes within the step with gravity's fall: a damper
  // c + h k toward the closing speed that meets the surface at the step's end
  // (an overlap opening faster than its spring pushes is let go unless it stays by the end)
  const bool closing = r.vn <= r.rest && r.depth - kEvalH * (r.vn + r.fall) >= 0;
  const bool stays = r.depth - kEvalH * (r.vn + r.fall) > 0;
  const double pushed = r.k * r.held - r.c * r.vn;
  const double fn = r.depth > 0 ? (stays ? pushed : std::max(0.0, pushed))
                    : closing   ? (r.c + kEvalH * r.k) * (*param(c, "penetration") / kEvalH - r.vn)
                                : 0.0;
  const Vec3 vt = vrel - r.vn * n;
  // sticking: the normal spring-damper, tangentially, towards the anchor; sliding: Coulomb
  const Vec3 strain = vec3_at(param(c, "anchor")) + moved - n.dot(moved) * n;
  const Vec3 stick = -(r.k * strain + r.c * vt);
  // sliding: Coulomb linearised about the held slip (mu fn along it, a damper across) while the
  // slip is faster than friction stops in a step; slower, a damper along the slip itself
  const double fmax = mu * std::max(fn, 0.0), held_slip = std::sqrt(vt.squaredNorm() + slip * slip);
  const Vec3 dir = vt / held_slip;
  const bool fast = held_slip * *param(c, "mass") > kEvalH * fmax;
  const Vec3 slide = fast ? Vec3(-fmax * (dir + (vt - vt.dot(dir) * dir) / held_slip)) : Vec3(-fmax * vt / held_slip);
  // friction needs a normal force: an opening contact, or a gap staying open, holds nothing
  const double sticking = mu * std::max(fn, 0.0) > 0 ? *param(c, "sticking") : 0.0;
  r.f = fn * n + sticking * stick + (1 - sticking) * slide;
  return r;
}

// Parameters by name from kForceTable (generic ranges; special cases only where the physics
// needs them), globals around their descriptor defaults, then per-force admissibility.
template <class K>
Case<K> random_case(Rng& rng) {
  const auto& fi = info_of(K::kType);
  for (;;) {
    Case<K> c;
    random_body(rng, c.body[0], c.ref);
    random_body(rng, c.body[1], c.ref + kRefWords);
    for (const auto& gi : g::kGlobalTable)
      for (uint32_t l = 0; l < gi.param.lanes; ++l)
        c.glob[gi.param.offset / 4 + l] = gi.param.lanes == 1 ? gi.default_value[l] * rng.uni(0.5, 2)
                                                              : gi.default_value[l] + rng.uni(-2, 2);
    for (uint32_t i = 0; i < fi.num_params; ++i) {
      const g::ParamInfo& pi = fi.params[i];
      if (pi.lanes == 0) continue;  // placeholder entry of a parameterless force
      double* p = c.inst + pi.offset / 4;
      const std::string n = pi.name;
      if (n == "normal") set3(p, rng.unit());
      else if (n == "penetration") p[0] = rng.uni(0.001, 0.05);
      else if (n == "friction") p[0] = rng.uni(0.2, 1.0);
      else if (n == "point") set3(p, vec3_at(c.body[0] + kPos) + rng.vec(-0.5, 0.5));
      else if (pi.lanes == 3) set3(p, rng.vec(-1, 1));  // off-centre attachments, wind, ...
      else p[0] = pi.has_min ? pi.min + rng.uni(0.5, 5) : rng.uni(-2, 2);
    }
    if (fi.name == std::string("cone_twist")) {  // its swing and twist are defined on unit axes
      for (const char* n : {"axis_a", "axis_b"}) set3(param(c, n), vec3_at(param(c, n)).normalized());
    }
    if (double* rest = param(c, "rest_length")) {  // stretched, with a well-defined direction
      const double L = (attachment(c, "point_b", 1) - attachment(c, "point_a", 0)).norm();
      if (L < 0.3) continue;
      *rest = rng.uni(0.2, 0.8) * L;
    }
    if (contact_like<K>()) {
      // The world's contact: a mass of a pebble to a crate, sticking or sliding, strained from
      // its anchor by up to the slop, in the tangent plane. The stiffness and damping are soft
      // (from the mass) or, a quarter of the time each, fixed around the old penalty values.
      const Vec3 n = vec3_at(param(c, "normal")), a = rng.vec(-0.005, 0.005);
      set3(param(c, "anchor"), a - n.dot(a) * n);
      *param(c, "mass") = rng.uni(0.2, 10);
      // the weight resting on it, as a mass: none, or up to a crate on a pebble
      *param(c, "load") = rng.uni(0, 1) < 0.5 ? 0 : rng.uni(0.1, 100);
      *param(c, "sticking") = rng.uni(0, 1) < 0.5 ? 0 : 1;
      // gravity's fall onto the contact in a step: none (a wall) to 0.3 m/s
      *param(c, "fall") = rng.uni(0, 1) < 0.25 ? 0 : -rng.uni(0, 0.3);
      // the depth its spring acts on: the world's hold depth, or the deeper one of two bodies
      // joints join
      *param(c, "hold") = rng.uni(0, 1) < 0.5 ? global(c, "contact_hold_depth") : 0.01;
      if (rng.uni(0, 1) < 0.25) *global_at(c, "contact_stiffness") = 1e5 * rng.uni(0.5, 2);
      if (rng.uni(0, 1) < 0.25) *global_at(c, "contact_damping") = 1e3 * rng.uni(0.5, 2);
      if (rng.uni(0, 1) < 0.75) {
        // Overlapping, once the bodies' motion since the reference pose is counted, by less
        // than the hold depth or more (the spring then holds that), well clear of the kinks at
        // 0, at the hold depth and of positive_part so central differences stay on one branch.
        const double hold = *param(c, "hold");
        const double depth = rng.uni(0, 1) < 0.5 ? rng.uni(0.1, 0.9) * hold : rng.uni(1.1, 10) * hold;
        *param(c, "penetration") += depth - contact_ref(c).depth;
        const ContactRef r = contact_ref(c);
        if (r.k * r.held - r.c * r.vn < 0.5 * r.k * r.held) continue;
      } else {
        // A gap, closing within the step with gravity's fall: depth in (h (vn + fall), 0), 1e-4 m
        // clear of both ends.
        const ContactRef r0 = contact_ref(c);
        if (r0.vn > -0.05) continue;
        const double lo = kEvalH * (r0.vn + r0.fall) + 1e-4, hi = -1e-4;
        if (lo >= hi) continue;
        *param(c, "penetration") += rng.uni(lo, hi) - r0.depth;
        const ContactRef r = contact_ref(c);
        if (!(r.depth < 0 && r.vn <= r.rest && r.depth - kEvalH * (r.vn + r.fall) > 0)) continue;
      }
    }
    return c;
  }
}

// ---- Jacobians --------------------------------------------------------------------------------

// m[kind][row][col]: kind 0 = dF/ddelta, 1 = dF/du.
struct Blocks {
  Mat6 m[2][2][2];
  bool listed[2][2][2] = {};
  Blocks() { for (auto& a : m) for (auto& b : a) for (auto& x : b) x.setZero(); }
};

template <class K, class T>
Blocks kernel_blocks(const std::vector<T>& out) {
  Blocks B;
  for (int i = 0; i < K::kNumBlocks; ++i) {
    const g::BlockSlot s = K::kBlocks[i];
    const int kind = s.kind == g::BlockKind::dF_du;
    B.listed[kind][s.row_body][s.col_body] = true;
    for (int col = 0; col < 6; ++col)
      for (int row = 0; row < 6; ++row)
        B.m[kind][s.row_body][s.col_body](row, col) = double(out[6 * K::kBodies + 36 * i + col * 6 + row]);
  }
  return B;
}

// Moves body `body` by +h along coordinate j of delta (kind 0) or u (kind 1); rotations are
// exact, q <- exp(h e) (x) q. The reference pose stays put: the contact points are material
// points that follow the body from there.
template <class K>
void perturb(Case<K>& c, int body, int kind, int j, double h) {
  double* b = c.body[body];
  if (kind == 1) { b[(j < 3 ? kVel : kAngVel) + j % 3] += h; return; }
  if (j < 3) b[kPos + j] += h;
  else set_quat(b, (Quat(Eigen::AngleAxisd(h, Vec3::Unit(j - 3))) * quat_at(b)).normalized());
}

// Central differences. h = 1e-6: truncation ~h^2 |F'''|/|F'| <= 1e-12 / (0.005)^2 ~ 4e-8 even at
// the shortest length scale here (slip_velocity regularising friction), while roundoff
// ~eps |F| / h ~ 1e-10 |F|; both well below the 1e-6 tolerance (1e-5 would let friction
// truncation through).
constexpr double kFdStep = 1e-6;

// The kernel's blocks are derivatives with the lagged() values held: so are these.
template <class K>
Blocks fd_blocks(const Case<K>& c) {
  Blocks B;
  const std::vector<double> held = held_values(c);
  for (int body = 0; body < K::kBodies; ++body)
    for (int kind = 0; kind < 2; ++kind)
      for (int j = 0; j < 6; ++j) {
        Case<K> cp = c, cm = c;
        perturb(cp, body, kind, j, kFdStep);
        perturb(cm, body, kind, j, -kFdStep);
        const auto fp = eval_f_held(cp, held), fm = eval_f_held(cm, held);
        for (int row = 0; row < K::kBodies; ++row)
          for (int i = 0; i < 6; ++i) B.m[kind][row][body](i, j) = (fp[6 * row + i] - fm[6 * row + i]) / (2 * kFdStep);
      }
  return B;
}

double f_norm(const std::vector<double>& out, int bodies) {
  double s = 0;
  for (int i = 0; i < 6 * bodies; ++i) s += out[i] * out[i];
  return std::sqrt(s);
}

struct Worst {
  double err = 0;
  void add(double e) { if (!(e <= err)) err = e; }  // NaN sticks
};

std::string sci(double x) {
  char b[32];
  std::snprintf(b, sizeof b, "%.3g", x);
  return b;
}

const char* kKindName[2] = {"dF_ddelta", "dF_du"};
constexpr int kStates = 32;

// For kStates random states: the norm-wise relative error of every listed block against FD or,
// with `unlisted`, the size of every FD block kBlocks leaves out. J_of(case) gives the kernel's.
template <class K, class JOf>
void check_jacobians(uint64_t seed, double tol, bool unlisted, JOf J_of) {
  SCOPED_TRACE(kernel_name<K>());
  ASSERT_TRUE(probe<K>().ok);
  Rng rng(seed);
  Worst worst;
  for (int s = 0; s < kStates; ++s) {
    const Case<K> c = random_case<K>(rng);
    const Blocks fd = fd_blocks(c), J = J_of(c);
    // Absolute floor per kind: 1e-2 of the largest listed block, far above FD noise (~1e-10 |F|)
    // yet small enough that an error in a minor block still shows.
    double scale[2] = {0, 0};
    for (int k = 0; k < 2; ++k)
      for (int r = 0; r < K::kBodies; ++r)
        for (int col = 0; col < K::kBodies; ++col)
          if (J.listed[k][r][col]) scale[k] = std::max(scale[k], fd.m[k][r][col].norm());
    const double any_scale = std::max({scale[0], scale[1], f_norm(eval_case<double>(c), K::kBodies), 1e-300});
    for (int k = 0; k < 2; ++k)
      for (int r = 0; r < K::kBodies; ++r)
        for (int col = 0; col < K::kBodies; ++col) {
          const std::string where = "state " + std::to_string(s) + " " + kKindName[k] + " row " +
                                    std::to_string(r) + " col " + std::to_string(col);
          const Mat6& f = fd.m[k][r][col];
          if (J.listed[k][r][col] && !unlisted) {
            const double e = (J.m[k][r][col] - f).norm() / std::max({f.norm(), 1e-2 * scale[k], 1e-300});
            worst.add(e);
            EXPECT_LT(e, tol) << where << "\nkernel:\n" << J.m[k][r][col] << "\nFD:\n" << f;
          } else if (!J.listed[k][r][col] && unlisted) {
            const double e = f.norm() / any_scale;
            worst.add(e);
            EXPECT_LT(e, 1e-6) << where << " is not listed in kBlocks but FD gives\n" << f;
          }
        }
  }
  ::testing::Test::RecordProperty(kernel_name<K>() + (unlisted ? "_worst_unlisted_norm" : "_worst_rel_err"), sci(worst.err));
}

// ---- Hand reference of F (independent of the generated code) -------------------------------

void put(std::vector<double>& F, int body, const Vec3& f, const Vec3& tau) {
  for (int i = 0; i < 3; ++i) { F[6 * body + i] = f[i]; F[6 * body + 3 + i] = tau[i]; }
}

// The joints straight from their descriptors' doc strings: soft at omega = 2 pi hertz on the
// heavier body's mass (and its largest principal moment bound, half its inertia's trace), limits
// as the contact's one-sided spring-damper, motors by their held fast/slow branch.
template <class K>
void joint_reference(const Case<K>& c, const std::string& name, std::vector<double>& F) {
  const BodyD A = body_of(c.body[0]), B = body_of(c.body[1]);
  auto p = [&](const char* n) { return *param(c, n); };
  auto dir = [&](int body, const char* n) -> Vec3 {
    const Vec3 d = vec3_at(param(c, n));
    if (body == 1 && !kPair<K>) return d;
    return (body ? B : A).R * d;
  };
  auto vel_at = [&](int body, const Vec3& q) -> Vec3 {
    if (body == 1 && !kPair<K>) return Vec3::Zero();
    const BodyD& X = body ? B : A;
    return X.v + X.w.cross(q - X.x);
  };
  auto add = [&](int body, const Vec3& f, const Vec3& tau) {
    if (body == 1 && !kPair<K>) return;
    for (int i = 0; i < 3; ++i) { F[6 * body + i] += f[i]; F[6 * body + 3 + i] += tau[i]; }
  };
  // a one-sided stop past a bound: `over` > 0 violated, `rate` its growth
  auto stop = [&](double over, double rate, double k, double cc) {
    if (over > 0) return std::max(k * over + cc * rate, 0.0);
    return over + kEvalH * rate > 0 ? k * over + cc * rate : 0.0;
  };
  const double omega = 2 * kPi * (p("hertz") > 0 ? p("hertz") : global(c, "joint_hertz"));
  const double zeta = p("damping_ratio") > 0 ? p("damping_ratio") : global(c, "joint_damping_ratio");
  const double ma = A.m, mb = kPair<K> ? B.m : 0.0, m = std::max(ma, mb);
  const double im = std::max(A.Iw.trace() / 2, kPair<K> ? B.Iw.trace() / 2 : 0.0);
  const double k = m * omega * omega, cc = 2 * zeta * m * omega;
  const double kr = im * omega * omega, cr = 2 * zeta * im * omega;
  const Vec3 pa = attachment(c, "point_a", 0), pb = attachment(c, "point_b", 1);
  const Vec3 wrel = (kPair<K> ? B.w : Vec3::Zero()) - A.w;
  const Vec3 vrel = vel_at(1, pb) - vel_at(0, pa);
  auto put_pair = [&](const Vec3& f_on_a) {
    add(0, f_on_a, (pa - A.x).cross(f_on_a));
    add(1, -f_on_a, (pb - B.x).cross(-f_on_a));
  };
  auto put_torque = [&](const Vec3& tau_on_b) { add(0, Vec3::Zero(), -tau_on_b); add(1, Vec3::Zero(), tau_on_b); };
  if (name == "distance") {
    const Vec3 d = pb - pa;
    const double len = std::sqrt(d.squaredNorm() + 1e-12);
    const Vec3 n = d / len;
    const double rate = vrel.dot(n);
    const double pull = p("max_length") > 0 ? stop(len - p("max_length"), rate, k, cc) : 0.0;
    const double push = p("min_length") > 0 ? stop(p("min_length") - len, -rate, k, cc) : 0.0;
    const double spring = p("spring_stiffness") * (len - p("rest_length")) + p("spring_damping") * rate;
    put_pair((pull - push + spring) * n);
    return;
  }
  // motor: the largest force or torque while the target is more than a step of it away
  auto motor = [&](double target, double rate, double inertia, double most) {
    if (most <= 0) return 0.0;
    const double err = target - rate;
    if (std::fabs(err) * inertia > kEvalH * most) return (err > 0 ? 1.0 : -1.0) * most;
    return inertia * omega * err;
  };
  if (name == "wheel") {
    const bool limited = p("lower") < p("upper");
    // the slider's hold onto the suspension line, its spring and stops along it; the hinge's
    // alignment of the axle and its motor on the spin
    const Vec3 ns = dir(0, "suspension_a"), d = pb - pa;
    const double travel = d.dot(ns), rate = vrel.dot(ns);
    const Vec3 across = -k * (d - travel * ns) - cc * (vrel - rate * ns);
    const double lim = limited ? stop(p("lower") - travel, -rate, k, cc) - stop(travel - p("upper"), rate, k, cc) : 0.0;
    const double spring = -(p("spring_stiffness") * (travel - p("spring_travel")) + p("spring_damping") * rate);
    const Vec3 fb = across + (lim + spring) * ns;
    add(0, -fb, (pb - A.x).cross(-fb));
    add(1, fb, (pb - B.x).cross(fb));
    const Vec3 na = dir(0, "axis_a"), nb = dir(1, "axis_b");
    const double spin = wrel.dot(na);
    const double ia = na.dot(A.Iw * na), ib = kPair<K> ? na.dot(B.Iw * na) : 0.0;
    const double iz = ib > 0 ? ia * ib / (ia + ib) : ia;
    const Vec3 align = -kr * na.cross(nb) - cr * (wrel - spin * na);
    put_torque(align + motor(p("motor_speed"), spin, iz, p("motor_torque")) * na);
    return;
  }
  const Vec3 na = dir(0, "axis_a"), nb = dir(1, "axis_b"), ua = dir(0, "ref_a"), ub = dir(1, "ref_b");
  // the frame's third axis, axis x ref in the body's frame, turned to the world
  auto third = [&](int body, const char* axis, const char* ref) -> Vec3 {
    const Vec3 t = vec3_at(param(c, axis)).cross(vec3_at(param(c, ref)));
    return body == 1 && !kPair<K> ? t : Vec3((body ? B : A).R * t);
  };
  const Vec3 ta = third(0, "axis_a", "ref_a"), tb = third(1, "axis_b", "ref_b");
  // A slider's lock is tuned to a's moment about b's point, where the force across its axis acts.
  const double il = name == "slider"
                        ? std::max(A.Iw.trace() / 2 + ma * (pb - A.x).squaredNorm(), kPair<K> ? B.Iw.trace() / 2 : 0.0)
                        : im;
  const Vec3 lock = -il * omega * omega / 2 * (na.cross(nb) + ua.cross(ub) + ta.cross(tb)) - 2 * zeta * il * omega * wrel;
  if (name == "fixed") {
    put_pair(k * (pb - pa) + cc * vrel);
    put_torque(lock);
    return;
  }
  if (name == "cone_twist") {
    put_pair(k * (pb - pa) + cc * vrel);
    // the swing: the angle between the twist axes, opened by b turning about na x nb
    const double sn = std::sqrt(nb.cross(na).squaredNorm() + 1e-12), swing = std::atan2(sn, na.dot(nb));
    const Vec3 e = na.cross(nb) / sn;
    // each limit tuned to the two moments about its axis in series, at most sixteen times the
    // lighter's and at most the heavier's
    auto stop_inertia = [&](const Vec3& axis) {
      const double ia = axis.dot(A.Iw * axis), ib = kPair<K> ? axis.dot(B.Iw * axis) : 0.0;
      return ib > 0 ? std::min(std::max(ia, ib), 16 * ia * ib / (ia + ib)) : ia;
    };
    const double isw = stop_inertia(e), ksw = isw * omega * omega, csw = 2 * zeta * isw * omega;
    const double cone = p("cone_angle") > 0 ? stop(swing - p("cone_angle"), wrel.dot(e), ksw, csw) : 0.0;
    // the twist: ref_b turned back by the shortest rotation taking nb onto na (Eigen's), from ref_a
    const Vec3 ubs = Eigen::Quaterniond::FromTwoVectors(nb, na) * ub;
    const double twist = std::atan2(ua.cross(ubs).dot(na), ua.dot(ubs)), rate = wrel.dot(na);
    const double itw = stop_inertia(na), ktw = itw * omega * omega, ctw = 2 * zeta * itw * omega;
    const double lim = p("twist_lower") < p("twist_upper")
                           ? stop(p("twist_lower") - twist, -rate, ktw, ctw) - stop(twist - p("twist_upper"), rate, ktw, ctw)
                           : 0.0;
    const Vec3 spring = -p("spring_stiffness") * (swing * e + twist * na) - p("spring_damping") * wrel;
    put_torque(-cone * e + lim * na + spring);
    return;
  }
  const bool limited = p("lower") < p("upper");
  if (name == "slider") {
    const Vec3 d = pb - pa;
    const double travel = d.dot(na), rate = vrel.dot(na);
    const Vec3 across = -k * (d - travel * na) - cc * (vrel - rate * na);
    const double mz = mb > 0 ? ma * mb / (ma + mb) : ma;
    const double lim = limited ? stop(p("lower") - travel, -rate, k, cc) - stop(travel - p("upper"), rate, k, cc) : 0.0;
    const double spring = -(p("spring_stiffness") * (travel - p("spring_travel")) + p("spring_damping") * rate);
    const Vec3 fb = across + (lim + motor(p("motor_speed"), rate, mz, p("motor_force")) + spring) * na;
    add(0, -fb, (pb - A.x).cross(-fb));
    add(1, fb, (pb - B.x).cross(fb));
    put_torque(lock);
    return;
  }
  // hinge
  put_pair(k * (pb - pa) + cc * vrel);
  const double rate = wrel.dot(na);
  const double angle = std::atan2(ua.cross(ub).dot(na), ua.dot(ub));
  const double ia = na.dot(A.Iw * na), ib = kPair<K> ? na.dot(B.Iw * na) : 0.0;
  const double iz = ib > 0 ? ia * ib / (ia + ib) : ia;
  const double lim = limited ? stop(p("lower") - angle, -rate, kr, cr) - stop(angle - p("upper"), rate, kr, cr) : 0.0;
  const double spring = -(p("spring_stiffness") * (angle - p("spring_angle")) + p("spring_damping") * rate);
  // the alignment across each of the two axes across the hinge's: between two bodies, tuned to the
  // moments about that axis in series, at most sixteen times that and at most the heavier's; to
  // the world, to the body's largest moment
  auto across_inertia = [&](const Vec3& axis) {
    const double ja = axis.dot(A.Iw * axis), jb = kPair<K> ? axis.dot(B.Iw * axis) : 0.0;
    return jb > 0 ? std::min(std::max(ja, jb), 16 * ja * jb / (ja + jb)) : im;
  };
  const Vec3 p1 = ua, p2 = na.cross(ua), mis = na.cross(nb), wp = wrel - rate * na;
  const double i1 = across_inertia(p1), i2 = across_inertia(p2);
  const Vec3 align = -omega * omega * (i1 * mis.dot(p1) * p1 + i2 * mis.dot(p2) * p2) -
                     2 * zeta * omega * (i1 * wp.dot(p1) * p1 + i2 * wp.dot(p2) * p2);
  put_torque(align + (lim + motor(p("motor_speed"), rate, iz, p("motor_torque")) + spring) * na);
}

template <class K>
bool reference_force(const Case<K>& c, std::vector<double>& F) {
  F.assign(6 * K::kBodies, 0.0);
  const BodyD A = body_of(c.body[0]), B = body_of(c.body[1]);
  auto vel_at = [&](int body, const Vec3& p) -> Vec3 {
    if (body == 1 && !kPair<K>) return Vec3::Zero();
    const BodyD& X = body ? B : A;
    return X.v + X.w.cross(p - X.x);
  };
  auto apply_pair = [&](const Vec3& pa, const Vec3& pb, const Vec3& f_on_a) {
    put(F, 0, f_on_a, (pa - A.x).cross(f_on_a));
    if (kPair<K>) put(F, 1, -f_on_a, (pb - B.x).cross(-f_on_a));
  };
  // By name, not ForceType, so this compiles whichever forces the descriptors declare.
  const std::string name = info_of(K::kType).name;
  if (name == "gravity") {
    put(F, 0, A.m * vec3_at(c.glob + offsetof(g::Island_Params, gravity) / 4), Vec3::Zero());
  } else if (name == "damping") {
    put(F, 0, -*param(c, "linear") * A.m * A.v, -*param(c, "angular") * (A.Iw * A.w));
  } else if (name == "gyroscopic") {
    put(F, 0, Vec3::Zero(), -A.w.cross(A.Iw * A.w));
  } else if (name == "air_drag") {
    const Vec3 vrel = A.v - vec3_at(param(c, "wind"));
    put(F, 0, -global(c, "air_density") * *param(c, "drag") * vrel.norm() * vrel, Vec3::Zero());
  } else if (name == "applied_wrench") {
    put(F, 0, vec3_at(param(c, "force_world")), vec3_at(param(c, "torque_world")));
  } else if (name == "spring") {
    const Vec3 pa = attachment(c, "point_a", 0), pb = attachment(c, "point_b", 1);
    const Vec3 n = (pb - pa).normalized();
    const double speed = n.dot(vel_at(1, pb) - vel_at(0, pa));
    apply_pair(pa, pb, (*param(c, "stiffness") * ((pb - pa).norm() - *param(c, "rest_length")) +
                        *param(c, "damping") * speed) * n);
  } else if (name == "point_to_point") {
    const Vec3 pa = attachment(c, "point_a", 0), pb = attachment(c, "point_b", 1);
    apply_pair(pa, pb, *param(c, "stiffness") * (pb - pa) + *param(c, "damping") * (vel_at(1, pb) - vel_at(0, pa)));
  } else if (name == "contact") {
    const ContactRef r = contact_ref(c);
    apply_pair(r.pa, r.pb, -r.f);
  } else if (name == "hinge" || name == "fixed" || name == "slider" || name == "distance" || name == "cone_twist" ||
             name == "wheel") {
    joint_reference(c, name, F);
  } else {
    return false;
  }
  return true;
}

// ---- SIMD ---------------------------------------------------------------------------------

// Lane-wise agreement of a batch result with per-lane float results: relative 1e-5 with a floor
// of 1e-5 of the largest magnitude in the output's group (the leading F or g, or its 6x6 block).
template <int W>
double compare_lanes(const std::vector<std::vector<float>>& want, const std::vector<Batch<W>>& got, int head,
                     const char* what) {
  Worst worst;
  for (int lane = 0; lane < W; ++lane)
    for (int o = 0; o < int(got.size()); ++o) {
      const int g0 = o < head ? 0 : o - (o - head) % 36, g1 = o < head ? head : g0 + 36;
      double scale = 0;
      for (int q = g0; q < g1; ++q) scale = std::max(scale, double(std::fabs(want[lane][q])));
      const double w = want[lane][o], v = got[o][lane];
      worst.add(std::fabs(v - w) / (std::fabs(w) + scale + 1e-30));
      EXPECT_NEAR(v, w, 1e-5 * (std::fabs(w) + scale) + 1e-30) << what << ", lane " << lane << " output " << o;
    }
  return worst.err;
}

template <int W>
void check_batch_lanes_match_float() {
  Rng rng(4000 + W);
  visit_tested_kernels([&](auto k) {
    using K = decltype(k);
    SCOPED_TRACE(kernel_name<K>() + " W=" + std::to_string(W));
    std::vector<Batch<W>> in(K::kInputs), out(K::kOutputs), fout(6 * K::kBodies);
    std::vector<std::vector<float>> want(W, std::vector<float>(K::kOutputs)), want_f(W);
    std::vector<float> soa(K::kInputs * W);
    for (int lane = 0; lane < W; ++lane) {  // lane i = instance i, each gathered from a packed island
      const Packed<K> p = pack(random_case<K>(rng));
      std::vector<float> fin(K::kInputs);
      gather(p, fin.data());
      gather(p, soa.data() + lane, true, W);
      K::template eval<float>(fin.data(), float(kEvalH), want[lane].data());
      want_f[lane].resize(6 * K::kBodies);
      K::template eval_f<float>(fin.data(), float(kEvalH), want_f[lane].data());
      for (int i = 0; i < K::kInputs; ++i) in[i].set(lane, fin[i]);
    }
    for (int i = 0; i < K::kInputs; ++i)  // a stride-W gather writes lane `lane` of the SoA batch
      for (int lane = 0; lane < W; ++lane) EXPECT_EQ(soa[i * W + lane], in[i][lane]) << "strided gather, input " << i;
    K::template eval<Batch<W>>(in.data(), Batch<W>(float(kEvalH)), out.data());
    K::template eval_f<Batch<W>>(in.data(), Batch<W>(float(kEvalH)), fout.data());
    double worst = std::max(compare_lanes(want, out, 6 * K::kBodies, "eval"),
                            compare_lanes(want_f, fout, 6 * K::kBodies, "eval_f"));
    Batch<W> h;
    std::vector<Batch<W>> iout(K::kImplicitOutputs);
    std::vector<std::vector<float>> want_i(W, std::vector<float>(K::kImplicitOutputs));
    std::vector<float> fin(K::kInputs);
    for (int lane = 0; lane < W; ++lane) {
      h.set(lane, float(rng.uni(1e-4, 1e-2)));
      for (int i = 0; i < K::kInputs; ++i) fin[i] = in[i][lane];
      K::template eval_implicit<float>(fin.data(), h[lane], want_i[lane].data());
    }
    K::template eval_implicit<Batch<W>>(in.data(), h, iout.data());
    worst = std::max(worst, compare_lanes(want_i, iout, 6 * K::kBodies, "eval_implicit"));
    ::testing::Test::RecordProperty(kernel_name<K>() + "_W" + std::to_string(W) + "_worst_rel_diff", sci(worst));
  });
}

template <class Fn>
void for_contact_kernels(Fn fn) {
  int n = 0;
  g::visit_kernels([&](auto k) {
    using K = decltype(k);
    if constexpr (K::kType == g::ForceType::contact) { ++n; fn(k); }
  });
  EXPECT_EQ(2, n) << "expected the contact pair and world kernels";
}

template <class K>
void expect_all_outputs_zero(const Case<K>& c, const std::string& what) {
  const auto od = eval_case<double>(c);
  const auto of = eval_case<float>(c);
  for (int o = 0; o < K::kOutputs; ++o) {
    EXPECT_EQ(0.0, od[o]) << what << ": double output " << o;
    EXPECT_EQ(0.0f, of[o]) << what << ": float output " << o;
  }
}

// ==== Tests ========================================================================================

TEST(ForceKernelTable, EveryForceHasKernelsWithWellFormedBlocks) {
  std::vector<int> seen(g::kNumForceTypes, 0);
  int kernels = 0;
  visit_tested_kernels([&](auto k) {
    using K = decltype(k);
    SCOPED_TRACE(kernel_name<K>());
    ++kernels;
    ++seen[static_cast<int>(K::kType)];
    EXPECT_EQ(K::kOutputs, 6 * K::kBodies + 36 * K::kNumBlocks);
    EXPECT_EQ(K::kBodies, kPair<K> ? 2 : 1);
    bool dup[2][2][2] = {};
    for (int i = 0; i < K::kNumBlocks; ++i) {
      const g::BlockSlot s = K::kBlocks[i];
      ASSERT_TRUE(s.row_body >= 0 && s.row_body < K::kBodies && s.col_body >= 0 && s.col_body < K::kBodies);
      bool& d = dup[s.kind == g::BlockKind::dF_du][s.row_body][s.col_body];
      EXPECT_FALSE(d) << "block " << i << " listed twice";
      d = true;
    }
  });
  for (const auto& f : g::kForceTable)
    if (force_tested(f.name)) EXPECT_GE(seen[static_cast<int>(f.type)], 1) << f.name << " has no kernel";
#ifdef CELLPHYS_TESTED_FORCES
  // Every name the build lists is a force of this set, so a misspelt one cannot pass unchecked.
  for (const char* p = CELLPHYS_TESTED_FORCES; *p;) {
    const char* e = std::strchr(p, ',');
    const std::string name = e ? std::string(p, e) : std::string(p);
    EXPECT_TRUE(std::any_of(std::begin(g::kForceTable), std::end(g::kForceTable),
                            [&](const g::ForceInfo& f) { return name == f.name; }))
        << "CELLPHYS_TESTED_FORCES names '" << name << "', which this force set lacks";
    p = e ? e + 1 : p + name.size();
  }
#endif
  EXPECT_GT(kernels, 0);
  RecordProperty("kernels", kernels);
}

TEST(ForceKernelInputs, ProbeMapsEveryGatheredInputToOneStateWord) {
  visit_tested_kernels([&](auto k) {
    using K = decltype(k);
    SCOPED_TRACE(kernel_name<K>());
    const Probe& pr = probe<K>();
    ASSERT_TRUE(pr.ok);
    RecordProperty(kernel_name<K>() + "_reads_ref", pr.reads_ref);
    // The double fill agrees with pack() + gather() on an ordinary random state...
    Rng rng(7);
    Case<K> c = random_case<K>(rng);
    std::vector<float> in(K::kInputs), in_null(K::kInputs);
    gather(pack(c), in.data());
    for (int i = 0; i < K::kInputs; ++i)
      EXPECT_EQ(in[i], float(c.region(pr.src[i].region)[pr.src[i].word])) << "input " << i;
    // ...and a null `ref` means "the reference pose is the current pose".
    for (int b = 0; b < 2; ++b) {
      set3(c.ref + kRefWords * b, vec3_at(c.body[b] + kPos));
      for (int l = 0; l < 4; ++l) c.ref[kRefWords * b + 4 + l] = c.body[b][kQuat + l];
    }
    gather(pack(c), in.data());
    gather(pack(c), in_null.data(), /*with_ref=*/false);
    for (int i = 0; i < K::kInputs; ++i) EXPECT_EQ(in[i], in_null[i]) << "input " << i;
  });
}

TEST(ForceKernelJacobian, DoubleBlocksMatchCentralDifferencesOfF) {
  visit_tested_kernels([&](auto k) {
    using K = decltype(k);
    check_jacobians<K>(1000 + static_cast<int>(K::kType), 1e-6, /*unlisted=*/false,
                       [](const Case<K>& c) { return kernel_blocks<K>(eval_case<double>(c)); });
  });
}

TEST(ForceKernelJacobian, UnlistedBlocksAreZeroByFiniteDifferences) {
  visit_tested_kernels([&](auto k) {
    using K = decltype(k);
    check_jacobians<K>(2000 + static_cast<int>(K::kType), 1e-6, /*unlisted=*/true,
                       [](const Case<K>& c) { return kernel_blocks<K>(eval_case<double>(c)); });
  });
}

TEST(ForceKernelJacobian, FloatBlocksMatchDoubleCentralDifferences) {
  visit_tested_kernels([&](auto k) {
    using K = decltype(k);
    check_jacobians<K>(3000 + static_cast<int>(K::kType), 1e-3, /*unlisted=*/false,
                       [](const Case<K>& c) { return kernel_blocks<K>(eval_case<float>(c)); });
  });
}

TEST(ForceKernelForce, MatchesIndependentEigenEvaluation) {
  visit_tested_kernels([&](auto k) {
    using K = decltype(k);
    SCOPED_TRACE(kernel_name<K>());
    const Probe& pr = probe<K>();
    ASSERT_TRUE(pr.ok);
    Rng rng(5000 + static_cast<int>(K::kType));
    Worst worst;
    for (int s = 0; s < kStates; ++s) {
      const Case<K> c = random_case<K>(rng);
      std::vector<double> ref;
      ASSERT_TRUE(reference_force(c, ref)) << "no hand reference for this force: add one to reference_force()";
      const auto out = eval_case<double>(c);
      std::vector<double> in(K::kInputs), fo(6 * K::kBodies);
      for (int i = 0; i < K::kInputs; ++i) in[i] = c.region(pr.src[i].region)[pr.src[i].word];
      K::template eval_f<double>(in.data(), kEvalH, fo.data());
      double d = 0, dfo = 0;
      for (int i = 0; i < 6 * K::kBodies; ++i) {
        d += (out[i] - ref[i]) * (out[i] - ref[i]);
        dfo += (fo[i] - ref[i]) * (fo[i] - ref[i]);
      }
      const double e = std::sqrt(std::max(d, dfo)) / std::max(f_norm(ref, K::kBodies), 1e-300);
      worst.add(e);
      EXPECT_LT(e, 1e-10) << "state " << s << " (eval or eval_f)";
    }
    RecordProperty(kernel_name<K>() + "_F_worst_rel_err", sci(worst.err));
  });
}

// A joint point's held arm is the point's offset from the centre of mass, and its share of the arm's
// turn is s = q^2 / (1 + q^2), q = h^2 |f| |r| / (I_lo + mu |r|^2) with I_lo = 4 det I / (tr I)^2
// and mu the pair's reduced mass (the body's mass against the world): the swing of the body about
// the point under the force, against the step (kinematics.turn_share).
TEST(ForceKernelImplicit, JointArmsHoldTheOffsetAndTheSwingShare) {
  if (!force_tested("point_to_point")) GTEST_SKIP() << "point_to_point's kernels are not checked in this build";
  int joints = 0;
  visit_tested_kernels([&](auto k) {
    using K = decltype(k);
    if (std::string(info_of(K::kType).name) != "point_to_point") return;
    SCOPED_TRACE(kernel_name<K>());
    Rng rng(8100 + static_cast<int>(K::kType));
    for (int s = 0; s < kStates; ++s) {
      const Case<K> c = random_case<K>(rng);
      const double h = rng.uni(1e-3, 0.1);
      std::vector<double> F(6 * K::kBodies), held(std::max(K::kHeld, 1));
      K::template eval_f<double>(inputs<double>(c).data(), h, F.data(), nullptr, held.data());
      for (int j = 0; j < K::kBodies; ++j) {
        ASSERT_GE(K::kJointArm[j], 0) << "body " << j;
        const BodyD B = body_of(c.body[j]);
        const Vec3 r = attachment(c, j == 0 ? "point_a" : "point_b", j) - B.x;
        const Vec3 f = vec3_at(&F[6 * j]);
        const double* I = c.body[j] + kInertia;
        Mat3 Ib;
        Ib << I[0], I[3], I[4], I[3], I[1], I[5], I[4], I[5], I[2];
        const double i_lo = 4 * Ib.determinant() / (Ib.trace() * Ib.trace());
        const double mu = kPair<K> ? B.m * body_of(c.body[1 - j]).m / (B.m + body_of(c.body[1 - j]).m) : B.m;
        const double q = h * h * f.norm() * r.norm() / (i_lo + mu * r.squaredNorm());
        EXPECT_LT((vec3_at(&held[K::kJointArm[j]]) - r).norm(), 1e-12 * (1 + r.norm())) << "state " << s;
        EXPECT_NEAR(held[K::kJointArm[j] + 3], q * q / (1 + q * q), 1e-9) << "state " << s << " q " << q;
        ++joints;
      }
    }
  });
  EXPECT_GT(joints, 0);
}

TEST(ForceKernelImplicit, GAndKMatchFAndBlocksOfEval) {
  visit_tested_kernels([&](auto k) {
    using K = decltype(k);
    SCOPED_TRACE(kernel_name<K>());
    ASSERT_TRUE(probe<K>().ok);
    // K_ij exists exactly for the body pairs with a dF/ddelta or dF/du block.
    const Blocks listed = kernel_blocks<K>(std::vector<double>(K::kOutputs));
    int pairs = 0;
    for (int i = 0; i < K::kBodies; ++i)
      for (int j = 0; j < K::kBodies; ++j) pairs += listed.listed[0][i][j] || listed.listed[1][i][j];
    ASSERT_EQ(pairs, K::kNumImplicitBlocks);
    ASSERT_EQ(K::kImplicitOutputs, 6 * K::kBodies + 36 * K::kNumImplicitBlocks);
    Rng rng(8000 + static_cast<int>(K::kType));
    Worst worst;
    for (int s = 0; s < kStates; ++s) {
      const Case<K> c = random_case<K>(rng);
      const double h = rng.uni(1e-4, 1e-2);
      const std::vector<double> out = eval_case<double>(c, h);
      const Blocks J = kernel_blocks<K>(out);
      std::vector<double> io(K::kImplicitOutputs);
      K::template eval_implicit<double>(inputs<double>(c).data(), h, io.data());
      // a joint point's arc, (1 - s) h^2/2 w x (w x r), from the arm and share eval_f holds
      std::vector<double> f_only(6 * K::kBodies), held(std::max(K::kHeld, 1));
      K::template eval_f<double>(inputs<double>(c).data(), h, f_only.data(), nullptr, held.data());
      for (int i = 0; i < K::kBodies; ++i) {
        Eigen::Matrix<double, 6, 1> g = Eigen::Map<const Eigen::Matrix<double, 6, 1>>(&out[6 * i]), Ju;
        double scale = g.norm();
        for (int j = 0; j < K::kBodies; ++j) {
          Eigen::Matrix<double, 6, 1> u;
          u << vec3_at(c.body[j] + kVel), vec3_at(c.body[j] + kAngVel);
          Ju = h * J.m[0][i][j] * u;
          if (K::kJointArm[j] >= 0) {
            const Vec3 w = vec3_at(c.body[j] + kAngVel), r = vec3_at(&held[K::kJointArm[j]]);
            const double share = held[K::kJointArm[j] + 3];
            EXPECT_GE(share, 0.0);
            EXPECT_LE(share, 1.0);
            Ju += J.m[0][i][j].leftCols(3) * ((1 - share) * h * h / 2 * w.cross(w.cross(r)));
          }
          g += Ju;
          scale += Ju.norm();
        }
        const double e = (Eigen::Map<const Eigen::Matrix<double, 6, 1>>(&io[6 * i]) - g).norm() / std::max(scale, 1e-300);
        worst.add(e);
        EXPECT_LT(e, 1e-12) << "state " << s << " g_" << i;
      }
      for (int b = 0; b < K::kNumImplicitBlocks; ++b) {
        const g::BlockSlot p = K::kImplicitBlocks[b];
      EXPECT_TRUE(listed.listed[0][p.row_body][p.col_body] || listed.listed[1][p.row_body][p.col_body]);
        const Mat6 want = h * J.m[1][p.row_body][p.col_body] + h * h * J.m[0][p.row_body][p.col_body];
        const double scale = h * J.m[1][p.row_body][p.col_body].norm() + h * h * J.m[0][p.row_body][p.col_body].norm();
        const double e = (Eigen::Map<const Mat6>(&io[6 * K::kBodies + 36 * b]) - want).norm() / std::max(scale, 1e-300);
        worst.add(e);
        EXPECT_LT(e, 1e-12) << "state " << s << " K_" << p.row_body << p.col_body;
      }
    }
    RecordProperty(kernel_name<K>() + "_implicit_worst_rel_err", sci(worst.err));
  });
}

// The runtime evaluates every kernel 8 lanes wide (spu/force_eval.cpp) on every path. Widths 4
// and 16 fill a native register of their own only on the SIMD paths; on the scalar path a
// Batch<W> is W scalar lanes whatever W (test_simd checks it op by op), and there these two
// widths only tripled this file's compile (ten minutes).
TEST(ForceKernelSimd, Batch8LanesMatchScalarFloat) { check_batch_lanes_match_float<8>(); }
#if defined(CELLPHYS_SIMD_PATH_AVX512) || defined(CELLPHYS_SIMD_PATH_AVX2)
TEST(ForceKernelSimd, Batch4LanesMatchScalarFloat) { check_batch_lanes_match_float<4>(); }
TEST(ForceKernelSimd, Batch16LanesMatchScalarFloat) { check_batch_lanes_match_float<16>(); }
#endif

TEST(ContactKernel, NoForceAndNoBlocksWhenSeparated) {
  for_contact_kernels([](auto k) {
    using K = decltype(k);
    SCOPED_TRACE(kernel_name<K>());
    ASSERT_TRUE(probe<K>().ok);
    Rng rng(6000);
    for (int s = 0; s < kStates; ++s) {
      Case<K> c = random_case<K>(rng);
      // A gap the step does not close, with gravity's fall (or one that opens). depth exactly 0
      // is left out: it is computed, so its sign there is rounding noise.
      const ContactRef r0 = contact_ref(c);
      const double beyond = std::min(kEvalH * (r0.vn + r0.fall), 0.0);
      *param(c, "penetration") += beyond - rng.uni(1e-6, 0.05) - r0.depth;
      const ContactRef r = contact_ref(c);
      ASSERT_LT(r.depth, 0);
      ASSERT_TRUE(r.vn > r.rest || r.depth - kEvalH * (r.vn + r.fall) < 0);
      // No normal force, so no friction either: sliding (a Coulomb force of zero) or sticking
      // (a friction cone of zero radius), whatever the strain of the anchor.
      for (int sticking : {0, 1}) {
        *param(c, "sticking") = sticking;
        expect_all_outputs_zero(c, "gap not closing, sticking " + std::to_string(sticking) + ", state " + std::to_string(s));
      }
    }
  });
}

// Touching at rest (zero depth, zero relative velocity, at the anchor): no force yet, but the
// step's normal block is there, h c + h^2 k, so the implicit step meets the surface instead of
// sinking for a step: as the spring-damper's if the computed depth rounds to an overlap, as the
// damper c + h k toward the surface if it rounds to a gap. A sticking contact's anchor holds it
// tangentially with the same block. The stiffness is the soft one, mass (2 pi hertz)^2, unless
// a fixed one is set.
TEST(ContactKernel, TouchingAtRestHasNoForceButTheNormalBlock) {
  for_contact_kernels([](auto k) {
    using K = decltype(k);
    SCOPED_TRACE(kernel_name<K>());
    Rng rng(6500);
    for (int s = 0; s < 4; ++s) {
      Case<K> c = random_case<K>(rng);
      for (int b = 0; b < 2; ++b) {  // both at rest, at their reference poses
        set3(c.body[b] + kVel, Vec3::Zero());
        set3(c.body[b] + kAngVel, Vec3::Zero());
        set3(c.ref + kRefWords * b, vec3_at(c.body[b] + kPos));
        for (int l = 0; l < 4; ++l) c.ref[kRefWords * b + 4 + l] = c.body[b][kQuat + l];
      }
      *param(c, "penetration") = 0;
      *param(c, "fall") = -kEvalH * 9.81;  // resting under gravity: the step would close it
      set3(param(c, "anchor"), Vec3::Zero());
      const bool sticking = s % 2, fixed = s >= 2;
      *param(c, "sticking") = sticking;
      *global_at(c, "contact_stiffness") = fixed ? 2e5 : 0;
      *param(c, "load") = 0;  // nothing rests on it yet
      const ContactRef r = contact_ref(c);
      SCOPED_TRACE(std::string(sticking ? "sticking" : "sliding") + (fixed ? ", fixed stiffness" : ", soft"));
      ASSERT_NEAR(r.depth, 0, 1e-12);  // computed: rounding either way
      const double h = kEvalH, step_block = h * r.c + h * h * r.k;
      const std::vector<double> out = eval_case<double>(c);
      EXPECT_LT(f_norm(out, K::kBodies), 1e-9 * r.k);
      const Vec3 n = vec3_at(param(c, "normal"));
      const Blocks J = kernel_blocks<K>(out);
      // a's own linear block of the step, h dF/du + h^2 dF/ddelta: moving a by n deepens the
      // contact by 1, so -(h c + h^2 k) n n^T. Sliding, with no normal force yet there is no
      // friction: nothing tangential. Marked sticking, the zero depth rounds to a load of either
      // sign: nothing tangential, or the anchor's -(h c + h^2 k) (I - n n^T) on top.
      const Eigen::Matrix3d normal = -step_block * n * n.transpose();
      const Eigen::Matrix3d block = h * h * J.m[0][0][0].topLeftCorner<3, 3>() + h * J.m[1][0][0].topLeftCorner<3, 3>();
      const double off = (block - normal).norm(), anchored = (block + step_block * Eigen::Matrix3d::Identity()).norm();
      EXPECT_LT(sticking ? std::min(off, anchored) : off, 1e-9 * step_block) << "kernel:\n" << block << "\nwant:\n" << normal;
    }
  });
}

TEST(ContactKernel, NormalForceClampsToZeroWhenSeparatingFast) {
  for_contact_kernels([](auto k) {
    using K = decltype(k);
    SCOPED_TRACE(kernel_name<K>());
    ASSERT_TRUE(probe<K>().ok);
    Rng rng(7000);
    for (int s = 0; s < kStates; ++s) {
      Case<K> c = random_case<K>(rng);
      while (contact_ref(c).depth <= 0) c = random_case<K>(rng);  // overlapping cases only
      const ContactRef r = contact_ref(c);
      // Make c vn = (1.5..10) k held: overlapping, but separating faster than the spring pushes,
      // and fast enough to leave the overlap within the step, gravity's fall counted.
      const double leaves = (r.depth / kEvalH - r.fall) * rng.uni(1.2, 3);
      const double dvn = std::max(rng.uni(1.5, 10) * r.k * r.held / r.c, leaves) - r.vn;
      const Vec3 n = vec3_at(param(c, "normal"));
      double* v = kPair<K> ? c.body[1] + kVel : c.body[0] + kVel;  // vrel = v_b(pb) - v_a(pa)
      set3(v, vec3_at(v) + (kPair<K> ? dvn : -dvn) * n);
      const ContactRef r2 = contact_ref(c);
      ASSERT_GT(r2.depth, 0);
      ASSERT_LT(r2.k * r2.held - r2.c * r2.vn, 0);
      ASSERT_LT(r2.depth - kEvalH * (r2.vn + r2.fall), 0);
      // No normal force, so no friction, sliding or sticking (see NoForceAndNoBlocksWhenSeparated).
      for (int sticking : {0, 1}) {
        *param(c, "sticking") = sticking;
        expect_all_outputs_zero(c, "separating fast, sticking " + std::to_string(sticking) + ", state " + std::to_string(s));
      }
    }
  });
}

}  // namespace
