// The world a server links: bodies on a shape dictionary, forces between them, and the step.
// Bad input is refused with a WorldError and changes nothing.
//
// One step, stage by stage (World::step in runtime/ppe/world.cpp; each stage is a function in
// a file of its own and is timed under its name in StepStats::times):
//   1. collide          runtime/ppe/step_collide.h    broad, mid (with planes) and narrow phase
//   2. wake             runtime/ppe/step_sleep.h      sleeping groups touched by awake bodies
//   3. push             runtime/ppe/step_push.h       deep overlap (spawns, teleports) moved out
//   4. build islands    runtime/ppe/step_islands.h    awake bodies joined by contacts and forces
//   5. decouple         runtime/ppe/step_decouple.h   islands too big for a local store cut in parts
//   6. integrate        runtime/ppe/step_integrate.h  pack, run on the kernels, check, unpack;
//                                                     a failed step halves inside the kernel
//   7. sleep            runtime/ppe/step_sleep.h      quiet islands put to sleep
//   8. events           runtime/ppe/step_events.h     touches begun and ended, sensors entered and left
#pragma once
#include <cstdint>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "cellphys/gen/force_table.h"
#include "runtime/ppe/body_state.h"
#include "runtime/ppe/shapes.h"
#include "runtime/ppe/step_stats.h"
#include "runtime/ppe/world_queries.h"
#include "runtime/spu/island_image.h"
#include "runtime/spu/krylov.h"
#include "runtime/spu/local_store.h"

namespace cellphys::ppe {

class WorldError : public std::invalid_argument {
 public:
  using std::invalid_argument::invalid_argument;
};

class IslandRunner;  // runtime/ppe/island_runner.h

using BodyId = uint32_t;
using ForceId = uint32_t;
inline constexpr BodyId kWorldBody = 0xFFFFFFFFu;  // the b side of a world-anchored force

/// A world's settings at their defaults. What each means, its bounds (checked by the World)
/// and its place in a scene file: the table in runtime/ppe/settings.cpp.
struct WorldSettings {
  float dt = 1.0f / 60.0f;
  /// The forces' globals (gravity, the contact's stiffness, ...), declared by the force
  /// descriptors with their defaults, bounds and places (gen::kGlobalTable).
  gen::Force_Globals globals;
  spu::Integrator integrator = spu::Integrator::implicit_split;
  spu::Solver solver = spu::Solver::cgs;
  float tolerance = 1e-3f;
  uint32_t max_halvings = 8;
  bool sleeping = true;
  int workers = 1;
  float contact_margin = 0.001f;
  float contact_load_depth = 1e-4f;
  float contact_joined_hold_depth = 0.01f;
  float joint_projection = 0.005f;
  size_t local_store_bytes = spu::LocalStore::kDefaultCapacity;
  size_t whole_island_bytes = spu::LocalStore::kMaxCapacity;
  uint32_t decouple_sweeps = 8;
  float decouple_tolerance = 1e-3f;
  float region_min[3] = {-1e4f, -1e4f, -1e4f};
  float region_max[3] = {1e4f, 1e4f, 1e4f};
  float sleep_linear = 0.05f;
  float sleep_angular = 0.05f;
  float sleep_time = 0.5f;
};

struct BodyDesc {
  uint32_t shape = 0;
  float scale = 1.0f;
  float mass = 0.0f;     // > 0, or use density
  float density = 0.0f;  // kg/m^3, used when mass is 0
  bool has_inertia = false;
  float inertia[6] = {};  // Ixx Iyy Izz Ixy Ixz Iyz, body axes (overrides the shape's)
  BodyState state;        // the orientation is normalised, with a warning, if not unit
  float friction = 0.5f;
  float linear_damping = 0.0f;   // 1/s
  float angular_damping = 0.0f;  // 1/s
  bool is_static = false;
  /// A sensor reports the bodies that overlap it (World::sensor_events) and exerts no force:
  /// nothing collides with it, and it does not wake what it holds.
  bool sensor = false;
};

/// A contact point as the last step saw it, for display (World::debug_contacts()).
struct DebugContact {
  BodyId a, b;                // b is kWorldBody for static geometry
  float point[3], normal[3];  // world; the normal from a to b
  float depth;                // m, > 0 when overlapping
  /// N: the normal force the step's linear solve applied there: the contact's spring-damper
  /// (or a landing's damper) linearised as the step linearises it, at the separating speed the
  /// step ended with (runtime/ppe/world_debug.cpp). Over a step its sum is the momentum the
  /// contact gave: a resting body's contacts sum to its weight.
  float force;
};
inline constexpr uint32_t kNoIsland = 0xFFFFFFFFu;

/// A coupling the last step's decoupling stage cut (runtime/ppe/step_decouple.h): a contact or a
/// force between two bodies of one island that landed in different parts, so each part held the
/// other body as a kinematic ghost. For display (World::cut_couplings()).
struct CutCoupling {
  BodyId a, b;
  ForceId force;    // the force's id, or kNoForce for a contact
  float point[3];   // a contact's point (world); zero for a force
  uint32_t island;  // the island it was cut in (as last_island numbers them)
};
inline constexpr ForceId kNoForce = 0xFFFFFFFFu;

/// Two bodies began or ended touching in the last step (World::contact_events()): for sounds,
/// damage and game logic. a < b; a static body is named by its own id.
struct ContactEvent {
  enum class Kind : uint8_t { begin, end };
  Kind kind;
  BodyId a, b;
  /// A begin's: the middle of the pair's contact points and their normal, from a to b (world).
  float point[3], normal[3];
  /// A begin's: the fastest closing speed among its points before the step (m/s).
  float approach_speed;
  /// A begin's: the normal impulse that stops the approach (N s): the change the pair's first step
  /// of touching made to their separating speed at the point beyond gravity's, plus the closing
  /// speed left at its end (a fast pair arrives in that step and stops in the next), times the
  /// pair's effective mass there.
  float impulse;
};

/// A body entered (begin) or left (end) a sensor in the last step (World::sensor_events()).
struct SensorEvent {
  enum class Kind : uint8_t { begin, end };
  Kind kind;
  BodyId sensor, visitor;
};

/// A force instance's parameters by name, as the force table declares them.
using ForceParams = std::vector<std::pair<std::string, std::vector<float>>>;

class World {
 public:
  explicit World(WorldSettings settings = {});
  ~World();
  World(const World&) = delete;
  World& operator=(const World&) = delete;

  ShapeDictionary& shapes() { return shapes_; }
  const ShapeDictionary& shapes() const { return shapes_; }
  const WorldSettings& settings() const { return settings_; }
  /// Changes settings between steps (validated; throws WorldError and keeps the old ones).
  void set_settings(const WorldSettings& s);

  BodyId add_body(const BodyDesc& d);
  void remove_body(BodyId id);
  /// A force of any generated type by name ("spring", "point_to_point", ...); b may be
  /// kWorldBody for a world-anchored force. Parameters by name; missing ones are zero.
  ForceId add_force(const std::string& type, BodyId a, BodyId b, const ForceParams& params);
  void remove_force(ForceId id);

  BodyState state(BodyId id) const;
  void set_state(BodyId id, const BodyState& s);  // wakes the body
  void apply_impulse(BodyId id, const float impulse[3], const float point[3]);  // world frame; wakes
  bool is_awake(BodyId id) const;
  bool is_static(BodyId id) const;
  bool is_sensor(BodyId id) const;
  bool has_body(BodyId id) const;   // added and not removed
  uint32_t shape(BodyId id) const;  // index in shapes()
  float scale(BodyId id) const;
  float mass(BodyId id) const;
  const float* inertia_body(BodyId id) const;
  std::vector<BodyId> bodies() const;  // live ids, ascending
  size_t num_bodies() const;

  /// Computes the islands with `runner` (compute nodes in other processes, say) instead of
  /// the in-process worker pool of settings().workers threads; nullptr goes back to the pool.
  /// Results are the same bits either way. The world shares ownership of the runner.
  void set_runner(std::shared_ptr<IslandRunner> runner);
  IslandRunner* runner() const;

  /// One step of settings().dt: the seven stages listed at the top of this file.
  const StepStats& step();
  const StepStats& last_stats() const { return stats_; }
  /// For display, read by nothing in the step (runtime/ppe/world_debug.cpp): the contacts of
  /// awake bodies from the last step and those kept by sleeping groups, in no promised order;
  /// a body's island in the last step (kNoIsland: asleep, static, or added since), and whether
  /// that island was decoupled (cut in parts, runtime/ppe/step_decouple.h), and the couplings
  /// its cuts crossed (as many as last_stats().cut_couplings counts).
  std::vector<DebugContact> debug_contacts() const;
  uint32_t last_island(BodyId id) const;
  bool island_decoupled(uint32_t island) const;
  const std::vector<CutCoupling>& cut_couplings() const;

  /// The last step's begin and end touches, in pair order; a removed body's touches end in the
  /// step after its removal. Pairs a joint joins do not collide, so never touch.
  const std::vector<ContactEvent>& contact_events() const;
  /// The last step's sensor entries and exits, in (sensor, visitor) order. Sensors do not sense
  /// each other; a body asleep inside a sensor stays inside.
  const std::vector<SensorEvent>& sensor_events() const;
  /// The bodies inside `sensor` as the last step's collision found them (at the poses the step
  /// started from; a sleeper stays inside), ascending.
  std::vector<BodyId> sensor_contents(BodyId sensor) const;
  /// Warnings from the last add/set call (e.g. a quaternion normalised).
  const std::vector<std::string>& warnings() const { return warnings_; }
  double kinetic_energy() const;
  /// Bitwise hash of every live body's state, for determinism checks.
  uint64_t state_hash() const;

  /// Queries between steps (runtime/ppe/world_queries.cpp, docs/queries.md), on every live
  /// body the filter lets through, asleep and static ones too, against its exact shape. They
  /// change nothing a step or state_hash() reads; queries may run on several threads at once
  /// (not during a step or another call that changes bodies). A direction need not be unit;
  /// distances are along its unit vector. Bad input (a non-finite origin, a zero direction, a
  /// negative or NaN distance, a bad shape) throws WorldError naming the argument.
  /// The first body the ray origin + t dir meets for 0 <= t <= max_dist (infinite allowed);
  /// a ray starting inside a body hits it at 0 with normal -dir.
  std::optional<QueryHit> ray_cast(const float origin[3], const float dir[3], float max_dist,
                                   const QueryFilter& filter = {}) const;
  /// Every body the ray meets within max_dist, nearest first (ties by body id), once each.
  std::vector<QueryHit> ray_cast_all(const float origin[3], const float dir[3], float max_dist,
                                     const QueryFilter& filter = {}) const;
  /// The bodies whose shapes overlap a sphere, or a box (half extents, orientation w x y z);
  /// ids ascending.
  std::vector<BodyId> overlap_sphere(const float centre[3], float radius, const QueryFilter& filter = {}) const;
  std::vector<BodyId> overlap_box(const float centre[3], const float half_extents[3], const float orientation[4],
                                  const QueryFilter& filter = {}) const;
  /// The first body `shape` at (position, orientation) meets moving along dir up to max_dist
  /// (runtime/ppe/shape_sweep.h: within 1e-5 m, never past the contact; a shape starting in
  /// a body hits it at 0).
  std::optional<QueryHit> shape_cast(const QueryShape& shape, const float position[3], const float orientation[4],
                                     const float dir[3], float max_dist, const QueryFilter& filter = {}) const;

  /// The whole world as versioned, checksummed bytes (runtime/ppe/snapshot.cpp): settings,
  /// shape dictionary, bodies (removed ones too, so ids stay), forces, sleeping groups and
  /// the step counter. A world restored from them steps on bit for bit like this one.
  std::vector<unsigned char> snapshot() const;
  /// A world from snapshot() bytes. Throws WorldError naming what is wrong (truncated,
  /// checksum, version, a bad record); nothing is half-restored.
  static std::unique_ptr<World> restore(const unsigned char* bytes, size_t size);

 private:
  struct Impl;
  WorldSettings settings_;
  ShapeDictionary shapes_;
  StepStats stats_;
  std::vector<std::string> warnings_;
  std::unique_ptr<Impl> impl_;
};

}  // namespace cellphys::ppe
