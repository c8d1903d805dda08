// One step of each integration method on an island held in the local store. A step either
// succeeds and commits the new state into the island's bodies, or fails and leaves them
// as they were; the kernel then halves the step.
#pragma once
#include "runtime/base/quat.h"
#include "runtime/spu/assembly.h"
#include "runtime/spu/krylov.h"
#include "runtime/spu/workspace.h"

namespace cellphys::spu {

/// What integrating one island did, over all its substeps and halvings (the kernel copies these
/// into its IslandReport).
struct IntegrationCounters {
  int solver_iterations = 0;
  int solves = 0;
  int last_solver_code = 0;
  int rejected = 0;  // adaptive steps rejected by the error estimate
};

struct StepContext {
  IslandView island;
  Workspace* ws = nullptr;
  Solver solver = Solver::cgs;
  SolveSettings solve;
  float error_tolerance = 1e-3f;  // Rosenbrock: local error per step, relative (absolute below 1)
  IntegrationCounters counters;
};

/// Builds the block structure once per island (implicit integrators).
bool prepare(StepContext& c);

/// split = true: linearly implicit Euler for every force but the gyroscopic torque, then the
/// conserving free-rotation update; split = false: the reference design's step.
bool step_implicit(StepContext& c, float h, bool split);
/// step_implicit in two halves around its force evaluation, so that several islands' forces
/// can be evaluated in one pass (evaluate_forces_together): the zeroed targets of the
/// implicit system at the island's state, then, once they hold the forces, the scaling,
/// solve and commit. targets + evaluate_forces + finish is step_implicit, bit for bit.
ForceTargets implicit_step_targets(StepContext& c, float h, bool split);
bool finish_implicit(StepContext& c, float h, bool split);

/// The commit's first half for bodies of one island or several: each body's new orientation
/// and angular velocity from the solve's velocity change (into the workspace's u0), the free
/// rotations eight at a time in SIMD lanes (kicked_free_rotations). *failed is set for a
/// body whose rotation does not converge, turns too far or is not finite; nothing is written
/// to the bodies.
class KickRotations {
 public:
  void add(StepContext& c, int body, float h, bool split, bool* failed);
  void flush();  // the last, partial group

 private:
  static constexpr int kLanes = 8;
  struct Item {
    StepContext* c;
    int body;
    bool* failed;
  };
  static void put(StepContext& c, int body, float h, const Quatd& q1, const Vec3d& w1, bool* failed);
  Item items_[kLanes] = {};
  const gen::Rigid_Body* bodies_[kLanes] = {};
  Vec3d w_kick_[kLanes] = {};
  float h_ = 0.0f;
  int n_ = 0;
};

/// finish_implicit in parts, so that several islands' diagonal blocks are inverted, and their
/// bodies' rotations committed, in shared SIMD lane groups: the island's blocks given to the
/// inverter (*failed set if one cannot be inverted); once it has flushed, the scaling and the
/// solve (false: the solve failed); the island's bodies given to the rotations; once they
/// have flushed and none failed, the commit. Bit for bit finish_implicit.
void add_implicit_diagonal(StepContext& c, BlockInverter& inverter, bool* failed);
bool solve_inverted(StepContext& c, float h);
void add_kick_rotations(StepContext& c, KickRotations& rotations, float h, bool split, bool* failed);
void commit_step(StepContext& c, float h);
/// ROS2 over h; *error receives the scaled local error estimate (<= 1 accepts). The state is
/// committed only when the step succeeds and the error is acceptable.
bool step_rosenbrock(StepContext& c, float h, float* error);
bool step_explicit(StepContext& c, float h, bool symplectic);
bool step_rk4(StepContext& c, float h);

}  // namespace cellphys::spu
