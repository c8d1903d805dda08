// Peer engines for the benchmark: one scene (scene::SceneDesc) built in cellphys, Bullet, ODE
// or MuJoCo with the same geometry, masses, inertias, gravity, friction and time step, stepped
// through one interface. Only the bench tool links these; the runtime never does.
//
// What each peer maps, and how (docs/bench.md has the full table):
//  - shapes: sphere, box (half extents), capsule (core along body z), hull (the cellphys
//    hull's re-centred vertices), plane (static); mesh and height field (static: cellphys's
//    triangles, or MuJoCo's hfield); compound (the parts cellphys re-centred on the centre of
//    mass, as a compound shape or several geoms on one body);
//  - masses and inertia tensors: taken from the cellphys world built from the same scene, so
//    density-given bodies and hulls weigh the same in every engine;
//  - friction: the geometric mean of the two bodies' coefficients, per contact;
//  - `applied_wrench`, `damping` forces, and `spring` in Bullet and ODE: applied by
//    the bench as external forces evaluated from the state at the start of each step (those
//    engines have no spring element); in MuJoCo a `spring` is a spatial tendon with the same
//    stiffness, damping and rest length (MuJoCo's own passive force); `point_to_point`: the engine's own ball joint, rigid, with its
//    default constraint softness; `gyroscopic`: the engine's own rigid-body dynamics;
//    `hinge`, `slider`, `fixed`, `distance`, `cone_twist`: the engine's own joint where it has
//    one, with points, axes and limits (and motors and springs where that joint has them;
//    a scene that needs what the joint lacks is refused; docs/bench.md has the table).
//  - contacts: each engine's own contact model (cellphys: penalty spring-dampers).
// A scene an engine cannot express throws Unsupported with the reason; no row is invented.
#pragma once
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "runtime/ppe/world.h"
#include "runtime/scene/scene.h"

namespace cellphys::bench {

struct Unsupported : std::runtime_error {
  using std::runtime_error::runtime_error;
};

/// Which engine and which of its configurations.
///   cellphys: variant = "<integrator>/<solver>" (e.g. implicit_split/cgs); tolerance > 0
///             overrides the scene's; workers > 0 overrides the scene's.
///   bullet:   "default" (10 solver iterations) or "tuned" (iterations, default 100)
///   ode:      "step" (dWorldStep, direct LCP) or "quickstep" (dWorldQuickStep, iterations, default 20)
///   mujoco:   "euler", "implicit" or "rk4"
struct EngineConfig {
  std::string engine = "cellphys";
  std::string variant;
  double dt = 0;        // 0: the scene's
  double tolerance = 0;
  int workers = 0;
  int iterations = 0;   // 0: the variant's default
};

struct State {
  double p[3], q[4], v[3], w[3];  // position, quaternion w x y z, velocity, angular velocity (world)
};

class Peer {
 public:
  virtual ~Peer() = default;
  virtual void step() = 0;
  /// The state of scene body i (scene order, static bodies included).
  virtual State state(size_t i) const = 0;
  /// Dynamic bodies currently simulated (not asleep), or -1 if the engine does not say.
  virtual long active_bodies() const { return -1; }
  /// Solver iterations of the last step, or -1.
  virtual double last_iterations() const { return -1; }
  /// 1 if the engine reports that the last step failed (cellphys: an island's solve failed and
  /// kept its start state; MuJoCo: a warning such as a bad acceleration, which resets the state),
  /// 0 if it reports none, -1 if the engine does not say (ODE, Bullet).
  virtual int last_step_failed() const { return -1; }
  /// The configuration as run (e.g. "bullet tuned (100 iterations)").
  virtual std::string label() const = 0;
};

/// Mass properties and hull geometry of every scene body, as cellphys computes them.
struct BodyInfo {
  double mass = 0;          // 0 for static bodies
  double inertia[6] = {};   // Ixx Iyy Izz Ixy Ixz Iyz, body axes
  int shape = -1;           // index into scene.shapes
  std::vector<double> hull_vertices;  // x y z, re-centred and scaled (hulls only)
  std::vector<double> hull_planes;    // nx ny nz d (n.x = d), scaled
  std::vector<int> hull_faces;        // per face: count, then vertex indices (outward, counter-clockwise)
  // Meshes and height fields: the dictionary's triangles (a height field's grid as cellphys
  // triangulates it), vertices x y z scaled, 3 indices a triangle, front counter-clockwise.
  std::vector<double> mesh_vertices;
  std::vector<int> mesh_triangles;
  // Compounds: the parts as cellphys stores them, re-centred on the body's centre of mass;
  // position scaled by the body's scale, scale the part's times the body's; a hull part's
  // geometry at that scale.
  struct Part {
    int shape = -1;  // index into scene.shapes
    double position[3] = {}, orientation[4] = {1, 0, 0, 0}, scale = 1;
    std::vector<double> hull_vertices, hull_planes;
    std::vector<int> hull_faces;
  };
  std::vector<Part> parts;
};
std::vector<BodyInfo> body_info(const scene::SceneDesc& scene);

/// Forces the bench applies itself (spring, applied_wrench, damping, body damping):
/// per scene body, force and torque about the centre of mass, world frame.
class ExternalForces {
 public:
  /// springs = false leaves `spring` forces to the engine (MuJoCo's tendons).
  ExternalForces(const scene::SceneDesc& scene, const std::vector<BodyInfo>& info, bool springs = true);
  bool empty() const { return terms_.empty(); }
  /// Computes forces for every body from states; out has 6 values per body (force, torque).
  void evaluate(const std::vector<State>& states, std::vector<double>& out) const;

 private:
  struct Term {
    int kind;  // 0 spring, 1 wrench, 2 damping
    int a = -1, b = -1;  // body indices; b = -1: world
    double pa[3] = {}, pb[3] = {}, k = 0, c = 0, rest = 0, f[3] = {}, t[3] = {};
  };
  std::vector<Term> terms_;
  std::vector<BodyInfo> info_;
};

/// Index of a scene body id, or -1 for "world".
int body_index(const scene::SceneDesc& scene, const std::string& id);

/// A joint force of the scene (point_to_point, hinge, slider, fixed, distance, cone_twist) as
/// the peers map it: its parameters (left out: 0), the axes normalised and each ref made
/// perpendicular to its axis (any perpendicular when none is given), and the pose quantities
/// at the scene's start in world coordinates. A static scene body as b is turned into the
/// world (b = -1, its point, axis and ref into world coordinates); a static body as a is
/// refused (Unsupported).
struct JointSpec {
  std::string type;
  size_t force = 0;  // index in scene.forces
  int a = -1, b = -1;  // scene bodies; b = -1: the world
  double pa[3] = {}, pb[3] = {};  // body frames (pb: world frame when b = -1)
  double axis_a[3] = {}, axis_b[3] = {}, ref_a[3] = {}, ref_b[3] = {};
  bool has_axis = false;  // axis_a and axis_b given
  double lower = 0, upper = 0;            // hinge (rad), slider (m); limited when lower < upper
  double motor_speed = 0, motor_max = 0;  // hinge motor_torque, slider motor_force; 0: no motor
  double spring_k = 0, spring_c = 0, spring_rest = 0;  // hinge spring_angle, slider spring_travel, distance rest_length
  double min_length = 0, max_length = 0;  // distance
  double cone_angle = 0, twist_lower = 0, twist_upper = 0;  // cone_twist
  // At the start, world frame: the joint's points, axes and refs, its angle (hinge: ref_a to
  // ref_b about axis_a; cone_twist: the twist) and travel (slider: b's point from a's along axis_a).
  double wpa[3] = {}, wpb[3] = {}, wna[3] = {}, wnb[3] = {}, wua[3] = {}, wub[3] = {};
  double angle0 = 0, travel0 = 0, length0 = 0;
  bool limited() const { return lower < upper; }
  bool twist_limited() const { return twist_lower < twist_upper; }
};
/// The scene's joints in force order (other forces are left out).
std::vector<JointSpec> scene_joints(const scene::SceneDesc& scene);
/// The force types scene_joints returns.
bool is_joint_type(const std::string& type);

std::unique_ptr<Peer> make_cellphys(const scene::SceneDesc& scene, const EngineConfig& c);
std::unique_ptr<Peer> make_bullet(const scene::SceneDesc& scene, const EngineConfig& c);
std::unique_ptr<Peer> make_ode(const scene::SceneDesc& scene, const EngineConfig& c);
std::unique_ptr<Peer> make_mujoco(const scene::SceneDesc& scene, const EngineConfig& c);
/// Dispatches on c.engine; throws Unsupported for a scene the engine cannot express and
/// std::invalid_argument for an unknown engine or variant.
std::unique_ptr<Peer> make_peer(const scene::SceneDesc& scene, const EngineConfig& c);

// Small helpers shared by the peers.
void quat_rotate(const double q[4], const double v[3], double out[3]);       // R(q) v
void quat_rotate_inv(const double q[4], const double v[3], double out[3]);   // R(q)^T v
/// World inertia-tensor product: R I R^T w.
void world_inertia_mul(const double q[4], const double inertia[6], const double w[3], double out[3]);

}  // namespace cellphys::bench
