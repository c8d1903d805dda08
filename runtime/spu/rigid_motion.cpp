#include "runtime/spu/rigid_motion.h"

#include <cmath>

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

Quatd advance_orientation(const Quatd& q, const Vec3d& w, double h) {
  return quat_normalized(quat_mul(quat_exp(w * h), q));
}

bool free_rotation(const Quatd& q0, const Mat3d& R0, const Vec3d& L, const float* inverse_inertia_body, double h,
                   Quatd* q1, Vec3d* omega1) {
  const Mat3d Iinv = symmetric<double>(inverse_inertia_body);
  const Vec3d Lb = mul_transpose(R0, L);  // body-frame momentum
  // Fixed point on the midpoint body rate: w = I^-1 (Lb + Lb') / 2 with Lb' = cay(-h w) Lb.
  Vec3d w = mul(Iinv, Lb), Lb1 = Lb;
  const float* s = inverse_inertia_body;
  // isotropic inertia: no gyroscopic torque, Lb' = Lb and w is the fixed point already
  bool converged = s[0] == s[1] && s[1] == s[2] && s[3] == 0.0f && s[4] == 0.0f && s[5] == 0.0f;
  const double scale = norm(Lb) + 1e-300;
  for (int it = 0; it < 60 && !converged; ++it) {
    // Cayley rotation of Lb by -h w: the quaternion (1, -h w / 2), normalised
    const Vec3d a = w * (-0.5 * h);
    const Vec3d next = mul(quat_to_matrix(quat_normalized(Quatd{1.0, a.x, a.y, a.z})), Lb);
    const double d = norm(next - Lb1);
    Lb1 = next;
    w = mul(Iinv, (Lb + Lb1) * 0.5);
    converged = d <= 1e-12 * scale;  // far below the float state's resolution
  }
  if (!converged) return false;
  // R1 = R0 cay(h w): body-frame increment on the right
  const Vec3d a = w * (0.5 * h);
  *q1 = quat_normalized(quat_mul(q0, quat_normalized(Quatd{1.0, a.x, a.y, a.z})));
  // the new rate from the new body-frame momentum, rotated to world
  const Vec3d wb = mul(Iinv, Lb1);
  *omega1 = mul(quat_to_matrix(*q1), wb);
  return std::isfinite(omega1->x) && std::isfinite(omega1->y) && std::isfinite(omega1->z);
}

}  // namespace cellphys::spu
