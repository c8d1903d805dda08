// The world's own records of bodies, forces, contacts and sleeping groups.
#pragma once
#include <cstdint>
#include <vector>

#include "cellphys/gen/kernel_types.h"
#include "runtime/ppe/body_state.h"
#include "runtime/ppe/shapes.h"
#include "runtime/spu/shape.h"

namespace cellphys::ppe {

struct WorldBody {
  bool alive = false, is_static = false, awake = true;
  bool sensor = false;  // overlaps reported, no contacts (BodyDesc::sensor)
  uint32_t shape = 0;
  float scale = 1.0f;
  float mass = 0.0f;
  float inertia[6] = {}, inverse_inertia[6] = {};  // body axes: xx yy zz xy xz yz
  BodyState state;
  float friction = 0.5f, linear_damping = 0.0f, angular_damping = 0.0f;
  float sleep_timer = 0.0f;
  int32_t sleep_group = -1;
};

struct WorldForce {
  bool alive = false;
  gen::ForceType type{};
  uint32_t a = 0, b = 0;                // world ids (b = kWorldBody for none / the world)
  std::vector<unsigned char> instance;  // packed instance, body fields filled at packing
};

/// A contact point of this step: a dynamic, b dynamic or the world (static geometry).
struct WorldContact {
  uint32_t a, b;
  spu::ContactPoint point;
  float friction;
  float mass = 0.0f;         // the contact's effective mass along its normal (kg)
  float load = 0.0f;         // what it carries, as a mass (kg), from the pair's memory
  float anchor[3] = {};      // friction strain at the start of the step (m, world frame)
  float sticking = 1.0f;     // 1: friction holds it to its anchor; 0: it slides
  float hold = 0.0f;         // deepest overlap its spring acts on (m), set by collide (joint_groups.h)
  float fall = 0.0f;         // how far gravity closes it in a step (m/s, 0 or less), set with hold
};

struct SleepGroup {
  std::vector<uint32_t> bodies;
  std::vector<WorldContact> contacts;  // valid while every member sleeps: nothing moved
};

spu::Pose pose_of(const WorldBody& b);

struct BodyMass {
  float mass;
  float inertia[6];
};
/// Mass and inertia about the centre of mass from the shape, its scale, and either a mass
/// (> 0) or a density; throws ShapeError on bad input.
BodyMass body_mass(const ShapeDictionary& shapes, uint32_t shape, float scale, float mass, float density);

/// Inverse of a symmetric 3x3 (xx yy zz xy xz yz); false if singular or not finite.
bool invert_inertia(const float* I, float* inverse);

}  // namespace cellphys::ppe
