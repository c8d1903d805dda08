// Rigid-body kinematics on the packed state: quaternions (w x y z, body to world), world
// inertia, W = M^-1, and the conserving free-rotation step of the default integrator.
#pragma once
#include "cellphys/gen/layouts.h"

namespace cellphys::spu {

struct Quat {
  double w, x, y, z;
};
struct Vec3d {
  double x, y, z;
};
struct Mat3d {
  double m[3][3];
};

Quat quat_mul(const Quat& a, const Quat& b);
Quat quat_normalized(const Quat& q);
/// exp of a rotation vector: the unit quaternion rotating by |r| about r.
Quat quat_exp(const Vec3d& r);
Mat3d quat_to_matrix(const Quat& q);
Vec3d mul(const Mat3d& A, const Vec3d& v);
Vec3d mul_transpose(const Mat3d& A, const Vec3d& v);
/// R S R^T for a symmetric S given as xx yy zz xy xz yz.
Mat3d rotate_sym(const Mat3d& R, const float* s6);

Quat orientation(const gen::Rigid_Body& b);
void set_orientation(gen::Rigid_Body& b, const Quat& q);  // normalises
Vec3d load3(const float* p);
void store3(float* p, const Vec3d& v);  // lane 3 (padding) set to 0

/// W_Element of a body at its current orientation.
void compute_w(const gen::Rigid_Body& b, gen::W_Element& w);

/// q <- exp(h w / 2) q: rotate by the world-frame angular velocity w over h.
Quat advance_orientation(const Quat& q, const Vec3d& w, double h);

/// Torque-free rotation over h from orientation q0 with world angular momentum L: the
/// implicit midpoint rule on Euler's equations in body axes, whose Cayley update is an exact
/// rotation. |L| and the kinetic energy are conserved to the fixed-point tolerance, and the
/// world momentum L is unchanged. Returns false if the fixed point does not converge
/// (the caller halves the step).
bool free_rotation(const Quat& q0, const Vec3d& L, const float* inertia_body, const float* inverse_inertia_body,
                   double h, Quat* q1, Vec3d* omega1);

}  // namespace cellphys::spu
