// Rigid-body kinematics on the packed state: a body's orientation (unit quaternion w x y z,
// body to world), world inertia, W = M^-1, and the conserving free-rotation step of the
// default integrator. The quaternion and matrix maths is runtime/base/quat.h.
#pragma once
#include "cellphys/gen/layouts.h"
#include "runtime/base/quat.h"

namespace cellphys::spu {

Quatd orientation(const gen::Rigid_Body& b);
void set_orientation(gen::Rigid_Body& b, const Quatd& q);  // normalises
void store3(float* p, const Vec3d& v);  // lane 3 (padding) set to 0

/// W_Element of a body at its current orientation.
void compute_w(const gen::Rigid_Body& b, gen::W_Element& w);
/// compute_w of bodies[0, n) into w[0, n), eight at a time in SIMD lanes: each the bits
/// compute_w gives it (the same operations, each rounded once, in the same order).
void compute_ws(const gen::Rigid_Body* bodies, int n, gen::W_Element* w);

/// q <- exp(h w / 2) q: rotate by the world-frame angular velocity w over h.
Quatd advance_orientation(const Quatd& q, const Vec3d& w, double h);

/// Torque-free rotation over h from orientation q0 with world angular momentum L: the
/// implicit midpoint rule on Euler's equations in body axes, whose Cayley update is an exact
/// rotation. |L| and the kinetic energy are conserved to the fixed-point tolerance, and the
/// world momentum L is unchanged. Returns false if the fixed point does not converge
/// (the caller halves the step).
/// R0 is quat_to_matrix(q0), which the caller has already made.
bool free_rotation(const Quatd& q0, const Mat3d& R0, const Vec3d& L, const float* inverse_inertia_body, double h,
                   Quatd* q1, Vec3d* omega1);

/// The free rotation of up to eight bodies (count, 1 to 8) at once, each in a SIMD lane, after
/// a kick took its angular velocity to w_kick[k]: from orientation q0 and momentum
/// L = I(q0) w_kick, as the default integrator commits a step. ok[k] false where
/// free_rotation would return false; otherwise q1[k] and omega1[k] have its bits.
void kicked_free_rotations(const gen::Rigid_Body* const* bodies, const Vec3d* w_kick, int count, double h, Quatd* q1,
                           Vec3d* omega1, bool* ok);

}  // namespace cellphys::spu
