// A body's state: what a step advances, and what World::state and set_state, the scene's
// bodies, snapshots, packed islands and the wire tables carry. The generated layouts
// (gen::Rigid_Body and its _Fields, the Wire_* tables) name these fields the same way, so one
// copy serves every pair of them.
#pragma once
#include <algorithm>

namespace cellphys::ppe {

struct BodyState {
  float position[3] = {};                           // centre of mass, world frame
  float orientation[4] = {1.0f, 0.0f, 0.0f, 0.0f};  // w x y z, body to world
  float velocity[3] = {};
  float angular_velocity[3] = {};                   // world frame
};

/// Copies position, orientation, velocity and angular_velocity between any two records with
/// those fields (BodyState, Rigid_Body, Rigid_Body_Fields, Wire_*). A padded vec3 field (the
/// packed Rigid_Body's) keeps its padding lane.
template <class From, class To>
void copy_state(const From& from, To& to) {
  std::copy(from.position, from.position + 3, to.position);
  std::copy(from.orientation, from.orientation + 4, to.orientation);
  std::copy(from.velocity, from.velocity + 3, to.velocity);
  std::copy(from.angular_velocity, from.angular_velocity + 3, to.angular_velocity);
}

}  // namespace cellphys::ppe
