#include "runtime/spu/rigid_motion.h"

#include <cmath>

namespace cellphys::spu {

Quat quat_mul(const Quat& a, const Quat& b) {
  return {a.w * b.w - a.x * b.x - a.y * b.y - a.z * b.z, a.w * b.x + a.x * b.w + a.y * b.z - a.z * b.y,
          a.w * b.y - a.x * b.z + a.y * b.w + a.z * b.x, a.w * b.z + a.x * b.y - a.y * b.x + a.z * b.w};
}

Quat quat_normalized(const Quat& q) {
  const double n = std::sqrt(q.w * q.w + q.x * q.x + q.y * q.y + q.z * q.z);
  return {q.w / n, q.x / n, q.y / n, q.z / n};
}

Quat quat_exp(const Vec3d& r) {
  const double a = std::sqrt(r.x * r.x + r.y * r.y + r.z * r.z);
  // sin(a/2)/a by its series near 0, where the quotient loses digits
  const double s = a < 1e-4 ? 0.5 - a * a / 48.0 : std::sin(0.5 * a) / a;
  return {std::cos(0.5 * a), s * r.x, s * r.y, s * r.z};
}

Mat3d quat_to_matrix(const Quat& q) {
  const double w = q.w, x = q.x, y = q.y, z = q.z;
  return {{{1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)},
           {2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)},
           {2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)}}};
}

Vec3d mul(const Mat3d& A, const Vec3d& v) {
  return {A.m[0][0] * v.x + A.m[0][1] * v.y + A.m[0][2] * v.z, A.m[1][0] * v.x + A.m[1][1] * v.y + A.m[1][2] * v.z,
          A.m[2][0] * v.x + A.m[2][1] * v.y + A.m[2][2] * v.z};
}

Vec3d mul_transpose(const Mat3d& A, const Vec3d& v) {
  return {A.m[0][0] * v.x + A.m[1][0] * v.y + A.m[2][0] * v.z, A.m[0][1] * v.x + A.m[1][1] * v.y + A.m[2][1] * v.z,
          A.m[0][2] * v.x + A.m[1][2] * v.y + A.m[2][2] * v.z};
}

static Mat3d sym(const float* s) {
  return {{{s[0], s[3], s[4]}, {s[3], s[1], s[5]}, {s[4], s[5], s[2]}}};
}

Mat3d rotate_sym(const Mat3d& R, const float* s6) {
  const Mat3d S = sym(s6);
  Mat3d RS{}, out{};
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      for (int k = 0; k < 3; ++k) RS.m[i][j] += R.m[i][k] * S.m[k][j];
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      for (int k = 0; k < 3; ++k) out.m[i][j] += RS.m[i][k] * R.m[j][k];
  return out;
}

Quat orientation(const gen::Rigid_Body& b) {
  return {b.orientation[0], b.orientation[1], b.orientation[2], b.orientation[3]};
}

void set_orientation(gen::Rigid_Body& b, const Quat& q) {
  const Quat n = quat_normalized(q);
  b.orientation[0] = static_cast<float>(n.w);
  b.orientation[1] = static_cast<float>(n.x);
  b.orientation[2] = static_cast<float>(n.y);
  b.orientation[3] = static_cast<float>(n.z);
}

Vec3d load3(const float* p) { return {p[0], p[1], p[2]}; }

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

Quat advance_orientation(const Quat& q, const Vec3d& w, double h) {
  return quat_normalized(quat_mul(quat_exp({h * w.x, h * w.y, h * w.z}), q));
}

bool free_rotation(const Quat& q0, const Vec3d& L, const float* inertia_body, const float* inverse_inertia_body,
                   double h, Quat* q1, Vec3d* omega1) {
  const Mat3d R0 = quat_to_matrix(q0);
  const Mat3d Iinv = sym(inverse_inertia_body);
  (void)inertia_body;
  const Vec3d Lb = mul_transpose(R0, L);  // body-frame momentum
  // Fixed point on the midpoint body rate: w = I^-1 (Lb + Lb') / 2 with Lb' = cay(-h w) Lb.
  Vec3d w = mul(Iinv, Lb), Lb1 = Lb;
  const float* s = inverse_inertia_body;
  // isotropic inertia: no gyroscopic torque, Lb' = Lb and w is the fixed point already
  bool converged = s[0] == s[1] && s[1] == s[2] && s[3] == 0.0f && s[4] == 0.0f && s[5] == 0.0f;
  const double scale = std::sqrt(Lb.x * Lb.x + Lb.y * Lb.y + Lb.z * Lb.z) + 1e-300;
  for (int it = 0; it < 60 && !converged; ++it) {
    // Cayley rotation of Lb by -h w: the quaternion (1, -h w / 2), normalised
    const Quat c = quat_normalized({1.0, -0.5 * h * w.x, -0.5 * h * w.y, -0.5 * h * w.z});
    const Vec3d next = mul(quat_to_matrix(c), Lb);
    const double d = std::sqrt((next.x - Lb1.x) * (next.x - Lb1.x) + (next.y - Lb1.y) * (next.y - Lb1.y) +
                               (next.z - Lb1.z) * (next.z - Lb1.z));
    Lb1 = next;
    w = mul(Iinv, {0.5 * (Lb.x + Lb1.x), 0.5 * (Lb.y + Lb1.y), 0.5 * (Lb.z + Lb1.z)});
    converged = d <= 1e-12 * scale;  // far below the float state's resolution
  }
  if (!converged) return false;
  // R1 = R0 cay(h w): body-frame increment on the right
  const Quat c = quat_normalized({1.0, 0.5 * h * w.x, 0.5 * h * w.y, 0.5 * h * w.z});
  *q1 = quat_normalized(quat_mul(q0, c));
  // the new rate from the new body-frame momentum, rotated to world
  const Vec3d wb = mul(Iinv, Lb1);
  *omega1 = mul(quat_to_matrix(*q1), wb);
  return std::isfinite(omega1->x) && std::isfinite(omega1->y) && std::isfinite(omega1->z);
}

}  // namespace cellphys::spu
