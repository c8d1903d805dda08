#include "testing/ragdoll.h"

#include <cmath>

#include "runtime/base/mat3.h"
#include "runtime/base/quat.h"
#include "runtime/base/vec3.h"

namespace cellphys::testing {

const char* const Ragdoll::kPartNames[kParts] = {"pelvis",      "chest",     "head",    "upper_arm_l",
                                                  "forearm_l",   "upper_arm_r", "forearm_r", "thigh_l",
                                                  "shank_l",     "thigh_r",   "shank_r"};

namespace {

enum class Kind { box, sphere, capsule };
struct Part {
  Kind kind;
  float size[3];    // box half extents; sphere radius; capsule radius, half height (body z)
  float centre[3];  // standing, feet at the origin, 1.8 m tall (facing +y, left at -x)
  float share;      // of the body's mass
};
// Proportions of a 1.8 m adult; mass shares after Winter's segment tables (trunk split in
// pelvis and chest, hands and feet with their limbs).
constexpr Part kPart[Ragdoll::kParts] = {
    {Kind::box, {0.16f, 0.10f, 0.08f}, {0, 0, 0.95f}, 0.14f},
    {Kind::box, {0.18f, 0.11f, 0.22f}, {0, 0, 1.25f}, 0.36f},
    {Kind::sphere, {0.11f, 0, 0}, {0, 0, 1.63f}, 0.08f},
    {Kind::capsule, {0.05f, 0.09f, 0}, {-0.24f, 0, 1.28f}, 0.028f},
    {Kind::capsule, {0.045f, 0.105f, 0}, {-0.24f, 0, 0.99f}, 0.022f},
    {Kind::capsule, {0.05f, 0.09f, 0}, {0.24f, 0, 1.28f}, 0.028f},
    {Kind::capsule, {0.045f, 0.105f, 0}, {0.24f, 0, 0.99f}, 0.022f},
    {Kind::capsule, {0.07f, 0.14f, 0}, {-0.09f, 0, 0.67f}, 0.10f},
    {Kind::capsule, {0.055f, 0.165f, 0}, {-0.09f, 0, 0.24f}, 0.06f},
    {Kind::capsule, {0.07f, 0.14f, 0}, {0.09f, 0, 0.67f}, 0.10f},
    {Kind::capsule, {0.055f, 0.165f, 0}, {0.09f, 0, 0.24f}, 0.06f},
};

struct JointSpec {
  const char* type;
  int a, b;
  float at[3];  // standing, world
  float axis[3], ref[3];
  float cone, lower, upper;
};
// Elbows bend the hand forward (+y), knees the foot back: a hinge's angle is b's turn from a
// about +x, positive towards +y.
constexpr JointSpec kJoint[] = {
    {"cone_twist", 0, 1, {0, 0, 1.03f}, {0, 0, 1}, {0, 1, 0}, 0.5f, -0.35f, 0.35f},      // spine
    {"cone_twist", 1, 2, {0, 0, 1.50f}, {0, 0, 1}, {0, 1, 0}, 0.6f, -0.8f, 0.8f},        // neck
    {"cone_twist", 1, 3, {-0.24f, 0, 1.42f}, {0, 0, -1}, {0, 1, 0}, 1.4f, -0.8f, 0.8f},  // left shoulder
    {"hinge", 3, 4, {-0.24f, 0, 1.14f}, {1, 0, 0}, {0, 0, -1}, 0, 0.0f, 2.4f},           // left elbow
    {"cone_twist", 1, 5, {0.24f, 0, 1.42f}, {0, 0, -1}, {0, 1, 0}, 1.4f, -0.8f, 0.8f},   // right shoulder
    {"hinge", 5, 6, {0.24f, 0, 1.14f}, {1, 0, 0}, {0, 0, -1}, 0, 0.0f, 2.4f},            // right elbow
    {"cone_twist", 0, 7, {-0.09f, 0, 0.88f}, {0, 0, -1}, {0, 1, 0}, 0.9f, -0.5f, 0.5f},  // left hip
    {"hinge", 7, 8, {-0.09f, 0, 0.46f}, {1, 0, 0}, {0, 0, -1}, 0, -2.4f, 0.0f},          // left knee
    {"cone_twist", 0, 9, {0.09f, 0, 0.88f}, {0, 0, -1}, {0, 1, 0}, 0.9f, -0.5f, 0.5f},   // right hip
    {"hinge", 9, 10, {0.09f, 0, 0.46f}, {1, 0, 0}, {0, 0, -1}, 0, -2.4f, 0.0f},          // right knee
};

}  // namespace

Ragdoll add_ragdoll(ppe::World& w, float height, float mass, const float pelvis[3], const float orientation[4],
                    float joint_friction, float friction) {
  const float s = height / 1.8f;
  Ragdoll r;
  const float* hip = kPart[0].centre;
  const Mat3d turn = quat_to_matrix(Quatd::load(orientation));
  for (int i = 0; i < Ragdoll::kParts; ++i) {
    const Part& p = kPart[i];
    ppe::BodyDesc d;
    if (p.kind == Kind::box) {
      const float half[3] = {p.size[0] * s, p.size[1] * s, p.size[2] * s};
      d.shape = w.shapes().add_box(half);
    } else if (p.kind == Kind::sphere) {
      d.shape = w.shapes().add_sphere(p.size[0] * s);
    } else {
      d.shape = w.shapes().add_capsule(p.size[0] * s, p.size[1] * s);
    }
    d.mass = p.share * mass;
    d.friction = friction;
    const float rel[3] = {(p.centre[0] - hip[0]) * s, (p.centre[1] - hip[1]) * s, (p.centre[2] - hip[2]) * s};
    const Vec3d turned = mul(turn, Vec3d::load(rel));
    for (int k = 0; k < 3; ++k) d.state.position[k] = float(pelvis[k] + turned[k]);
    for (int k = 0; k < 4; ++k) d.state.orientation[k] = orientation[k];
    r.parts[i] = w.add_body(d);
  }
  const float damper = joint_friction * (mass / 70.0f) * s * s;
  for (const JointSpec& j : kJoint) {
    RagdollJoint rj;
    rj.type = j.type;
    rj.a = j.a, rj.b = j.b;
    for (int k = 0; k < 3; ++k) {
      rj.point_a[k] = (j.at[k] - kPart[j.a].centre[k]) * s;
      rj.point_b[k] = (j.at[k] - kPart[j.b].centre[k]) * s;
      rj.axis[k] = j.axis[k];
      rj.ref[k] = j.ref[k];
    }
    rj.cone = j.cone, rj.lower = j.lower, rj.upper = j.upper;
    auto v3 = [](const std::array<float, 3>& v) { return std::vector<float>(v.begin(), v.end()); };
    ppe::ForceParams params = {{"point_a", v3(rj.point_a)}, {"point_b", v3(rj.point_b)}, {"axis_a", v3(rj.axis)},
                               {"axis_b", v3(rj.axis)},     {"ref_a", v3(rj.ref)},       {"ref_b", v3(rj.ref)},
                               {"spring_damping", {damper}}};
    if (rj.type == "cone_twist") {
      params.push_back({"cone_angle", {rj.cone}});
      params.push_back({"twist_lower", {rj.lower}});
      params.push_back({"twist_upper", {rj.upper}});
    } else {
      params.push_back({"lower", {rj.lower}});
      params.push_back({"upper", {rj.upper}});
    }
    rj.force = w.add_force(rj.type, r.parts[j.a], r.parts[j.b], params);
    r.joints.push_back(rj);
  }
  return r;
}

}  // namespace cellphys::testing
