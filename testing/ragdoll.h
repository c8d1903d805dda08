// A ragdoll of 11 bodies (pelvis, chest, head, upper arms, forearms, thighs, shanks) held by the
// joint descriptors: cone-twist joints at the spine, neck, shoulders and hips, hinges at the
// elbows and knees, each with the limits of a human body. Shared by the joint tests and the
// ragdoll_pile scene (examples/scenes/make_scenes.py writes the same bodies and joints).
#pragma once
#include <array>
#include <string>
#include <vector>

#include "runtime/ppe/world.h"

namespace cellphys::testing {

struct RagdollJoint {
  std::string type;  // "cone_twist" or "hinge"
  int a, b;          // part indices (Ragdoll::parts)
  ppe::ForceId force;
  std::array<float, 3> point_a, point_b;  // body frames
  std::array<float, 3> axis;              // twist or hinge axis, the same in both body frames
  std::array<float, 3> ref;               // across the axis, the same in both body frames
  float cone = 0, lower = 0, upper = 0;   // cone angle; twist or hinge angle bounds (rad)
};

struct Ragdoll {
  static constexpr int kParts = 11;
  static const char* const kPartNames[kParts];
  std::array<ppe::BodyId, kParts> parts{};
  std::vector<RagdollJoint> joints;  // 10
};

/// A ragdoll `height` metres tall of `mass` kg (proportions and mass shares of an adult),
/// standing with its feet at the origin in its own frame, then turned by `orientation`
/// (w x y z) about its pelvis and its pelvis put at `pelvis`. `joint_friction` is each joint's
/// damper on the relative turn (N m s/rad) for a 70 kg, 1.8 m body, scaled with mass × height².
Ragdoll add_ragdoll(ppe::World& w, float height, float mass, const float pelvis[3], const float orientation[4],
                    float joint_friction = 0.5f, float friction = 0.6f);

}  // namespace cellphys::testing
