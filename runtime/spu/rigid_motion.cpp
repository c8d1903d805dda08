#include "runtime/spu/rigid_motion.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstring>

#include "runtime/base/double_lanes.h"

namespace cellphys::spu {

Quatd orientation(const gen::Rigid_Body& b) { return Quatd::load(b.orientation); }

void set_orientation(gen::Rigid_Body& b, const Quatd& q) {
  const Quatd n = quat_normalized(q);
  b.orientation[0] = static_cast<float>(n.w);
  b.orientation[1] = static_cast<float>(n.x);
  b.orientation[2] = static_cast<float>(n.y);
  b.orientation[3] = static_cast<float>(n.z);
}

void store3(float* p, const Vec3d& v) {
  p[0] = static_cast<float>(v.x);
  p[1] = static_cast<float>(v.y);
  p[2] = static_cast<float>(v.z);
  p[3] = 0.0f;
}

void compute_w(const gen::Rigid_Body& b, gen::W_Element& w) {
  const Mat3d Iinv = rotate_sym(quat_to_matrix(orientation(b)), b.inverse_inertia_body);
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) w.inverse_inertia_world[4 * r + c] = static_cast<float>(Iinv.m[r][c]);
    w.inverse_inertia_world[4 * r + 3] = 0.0f;
  }
  w.inverse_mass = b.inverse_mass;
}

void compute_ws(const gen::Rigid_Body* bodies, int n, gen::W_Element* w) {
  constexpr int kLanes = DoubleLanes::kLanes;
  for (int first = 0; first < n; first += kLanes) {
    const int lanes = std::min(kLanes, n - first);
    // the lanes' inputs transposed in plain arrays, then each loaded whole (a lane set at a
    // time, each vector waited for its own stores eight times)
    alignas(64) double in[10][kLanes];  // w x y z, then xx yy zz xy xz yz
    for (int l = 0; l < kLanes; ++l) {  // idle lanes repeat the last body
      const gen::Rigid_Body& b = bodies[first + std::min(l, lanes - 1)];
      for (int k = 0; k < 4; ++k) in[k][l] = double(b.orientation[k]);
      for (int k = 0; k < 6; ++k) in[4 + k][l] = double(b.inverse_inertia_body[k]);
    }
    DoubleLanes v[10];
    for (int k = 0; k < 10; ++k) std::memcpy(&v[k].v, in[k], sizeof in[k]);
    const Quat<DoubleLanes> q{v[0], v[1], v[2], v[3]};
    const Mat3<DoubleLanes> S = symmetric<DoubleLanes>(v + 4);
    const Mat3<DoubleLanes> Iinv = rotate_sym_matrix(quat_to_matrix(q), S);
    for (int l = 0; l < lanes; ++l) {
      gen::W_Element& wl = w[first + l];
      for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) wl.inverse_inertia_world[4 * r + c] = static_cast<float>(Iinv.m[r][c][l]);
        wl.inverse_inertia_world[4 * r + 3] = 0.0f;
      }
      wl.inverse_mass = bodies[first + l].inverse_mass;
    }
  }
}

Quatd advance_orientation(const Quatd& q, const Vec3d& w, double h) {
  return quat_normalized(quat_mul(quat_exp(w * h), q));
}

namespace {

template <class T, class M>
Vec3<T> pick3(M m, const Vec3<T>& a, const Vec3<T>& b) {
  return {pick(m, a.x, b.x), pick(m, a.y, b.y), pick(m, a.z, b.z)};
}

// free_rotation over one body (T double, M bool) or eight (DoubleLanes, LaneMask): the same
// operations in the same order either way. A lane that has converged keeps its values while
// the others iterate on, so each lane takes the iterations it takes alone. Returns which
// converged; *q1 and *omega1 are written for all.
template <class T, class M>
M free_rotation_of(const Quat<T>& q0, const Mat3<T>& R0, const Vec3<T>& L, const Mat3<T>& Iinv, M isotropic, double h,
                   Quat<T>* q1, Vec3<T>* omega1) {
  const Vec3<T> Lb = mul_transpose(R0, L);  // body-frame momentum
  // Fixed point on the midpoint body rate: w = I^-1 (Lb + Lb') / 2 with Lb' = cay(-h w) Lb.
  Vec3<T> w = mul(Iinv, Lb), Lb1 = Lb;
  // isotropic inertia: no gyroscopic torque, Lb' = Lb and w is the fixed point already
  M converged = isotropic;
  const T scale = norm(Lb) + T(1e-300);
  for (int it = 0; it < 60 && !every(converged); ++it) {
    // Cayley rotation of Lb by -h w: the quaternion (1, -h w / 2), normalised
    const Vec3<T> a = w * T(-0.5 * h);
    const Vec3<T> next = mul(quat_to_matrix(quat_normalized(Quat<T>{T(1.0), a.x, a.y, a.z})), Lb);
    const T d = norm(next - Lb1);
    Lb1 = pick3(converged, Lb1, next);
    w = pick3(converged, w, mul(Iinv, (Lb + Lb1) * T(0.5)));
    converged = converged | (d <= T(1e-12) * scale);  // far below the float state's resolution
  }
  // R1 = R0 cay(h w): body-frame increment on the right
  const Vec3<T> a = w * T(0.5 * h);
  *q1 = quat_normalized(quat_mul(q0, quat_normalized(Quat<T>{T(1.0), a.x, a.y, a.z})));
  // the new rate from the new body-frame momentum, rotated to world
  const Vec3<T> wb = mul(Iinv, Lb1);
  *omega1 = mul(quat_to_matrix(*q1), wb);
  return converged;
}

bool isotropic(const float* s) { return s[0] == s[1] && s[1] == s[2] && s[3] == 0.0f && s[4] == 0.0f && s[5] == 0.0f; }
bool finite(const Vec3d& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

}  // namespace

bool free_rotation(const Quatd& q0, const Mat3d& R0, const Vec3d& L, const float* inverse_inertia_body, double h,
                   Quatd* q1, Vec3d* omega1) {
  Quatd q;
  Vec3d w;
  if (!free_rotation_of(q0, R0, L, symmetric<double>(inverse_inertia_body), isotropic(inverse_inertia_body), h, &q, &w))
    return false;
  *q1 = q, *omega1 = w;
  return finite(w);
}

void kicked_free_rotations(const gen::Rigid_Body* const* bodies, const Vec3d* w_kick, int count, double h, Quatd* q1,
                           Vec3d* omega1, bool* ok) {
  using T = DoubleLanes;
  assert(count >= 1 && count <= T::kLanes);
  if (count < 1) return;
  Quat<T> q0;
  Vec3<T> wk;
  Mat3<T> inertia, Iinv;
  bool iso[T::kLanes];
  for (int l = 0; l < T::kLanes; ++l) {
    const int k = l < count ? l : count - 1;  // idle lanes repeat the last body; their results are dropped
    const gen::Rigid_Body& b = *bodies[k];
    const Quatd q = orientation(b);
    q0.w.set(l, q.w), q0.x.set(l, q.x), q0.y.set(l, q.y), q0.z.set(l, q.z);
    wk.x.set(l, w_kick[k].x), wk.y.set(l, w_kick[k].y), wk.z.set(l, w_kick[k].z);
    const Mat3d S = symmetric<double>(b.inertia_body), Si = symmetric<double>(b.inverse_inertia_body);
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) inertia.m[r][c].set(l, S.m[r][c]), Iinv.m[r][c].set(l, Si.m[r][c]);
    iso[l] = isotropic(b.inverse_inertia_body);
  }
  const Mat3<T> R0 = quat_to_matrix(q0);
  const Vec3<T> L = mul(rotate_sym_matrix(R0, inertia), wk);
  Quat<T> q;
  Vec3<T> w;
  const LaneMask converged = free_rotation_of(q0, R0, L, Iinv, lanes_where(iso), h, &q, &w);
  for (int l = 0; l < count && l < T::kLanes; ++l) {
    q1[l] = {q.w[l], q.x[l], q.y[l], q.z[l]};
    omega1[l] = {w.x[l], w.y[l], w.z[l]};
    ok[l] = converged[l] && finite(omega1[l]);
  }
}

}  // namespace cellphys::spu
