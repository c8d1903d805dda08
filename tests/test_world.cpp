// The world, scene by scene: resting and stacking, rolling and sliding on an incline against
// closed forms, the reference design's 65-box pile (contacts, settling, sleep), a sparse 1,000-body world
// whose cost follows its active bodies, island partition, decoupling a 300-box pile to fit the
// local store, bit-identical results across worker counts, refusal of bad input without side
// effects, and sleeping and waking.
//
// Scenes use the default WorldSettings (implicit_split at 60 Hz, soft contacts at 30 Hz and damping
// ratio 2 per contact mass or load: docs/contacts.md) and the reference design's 1 kg boxes of
// 0.25 m half-extent unless a test says otherwise. Criteria are physical; a scene that misbehaves
// is a runtime defect to fix, not a tolerance to widen.
#include <gtest/gtest.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <functional>
#include <limits>
#include <string>
#include <vector>

#include "runtime/ppe/shapes.h"
#include "runtime/ppe/world.h"
#include "testing/scenes.h"
#include "tests/support/record.h"

namespace {

using namespace cellphys;
using namespace cellphys::testing;
using cellphys::test_support::record;
using ppe::BodyDesc;
using ppe::BodyState;
using ppe::ShapeError;
using ppe::StepStats;
using ppe::WorldError;
using ppe::WorldSettings;

constexpr double kPi = 3.14159265358979323846;
constexpr float kG = 9.81f;
constexpr int kHz = 60;

double norm3(const float* v) { return std::sqrt(double(v[0]) * v[0] + double(v[1]) * v[1] + double(v[2]) * v[2]); }
double dot3(const float* a, const float* b) { return double(a[0]) * b[0] + double(a[1]) * b[1] + double(a[2]) * b[2]; }
double dist3(const float* a, const float* b) {
  const double d[3] = {double(a[0]) - b[0], double(a[1]) - b[1], double(a[2]) - b[2]};
  return std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
}
bool finite_state(const BodyState& s) {
  for (float x : s.position) if (!std::isfinite(x)) return false;
  for (float x : s.orientation) if (!std::isfinite(x)) return false;
  for (float x : s.velocity) if (!std::isfinite(x)) return false;
  for (float x : s.angular_velocity) if (!std::isfinite(x)) return false;
  return true;
}

// Least-squares slope of y(t).
double slope(const std::vector<double>& t, const std::vector<double>& y) {
  const double n = double(t.size());
  double st = 0, sy = 0, stt = 0, sty = 0;
  for (size_t i = 0; i < t.size(); ++i) st += t[i], sy += y[i], stt += t[i] * t[i], sty += t[i] * y[i];
  return (n * sty - st * sy) / (n * stt - st * st);
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0.0 : v[v.size() / 2];
}

// ---------------------------------------------------------------------------------------------
// 1. Resting

TEST(World, BoxRestingOnPlaneStaysWithinOneMillimetreForTenSecondsAndFallsAsleep) {
  World w;
  ground_plane(w);
  const float half[3] = {0.25f, 0.25f, 0.25f}, p0[3] = {0.0f, 0.0f, 0.25f};  // touching the ground
  const BodyId box = add_box(w, half, 1.0f, p0);
  double worst = 0;
  int asleep_at = -1;
  for (int i = 1; i <= 10 * kHz; ++i) {
    w.step();
    const BodyState s = w.state(box);
    ASSERT_TRUE(finite_state(s)) << "step " << i;
    worst = std::max(worst, dist3(s.position, p0));
    if (asleep_at < 0 && !w.is_awake(box)) asleep_at = i;
  }
  record("box_max_drift_m", worst);
  record("box_final_drift_m", dist3(w.state(box).position, p0));
  record("box_asleep_after_s", asleep_at / double(kHz));
  // The static compression is m g / (4 k) = 0.025 mm: anything near 1 mm is the contact misbehaving.
  EXPECT_LT(worst, 1e-3) << "the box moved more than 1 mm at some step";
  EXPECT_LT(dist3(w.state(box).position, p0), 1e-3);
  EXPECT_FALSE(w.is_awake(box));
  EXPECT_GT(asleep_at, 0);
}

// A stack placed exactly touching carries its weight with sub-millimetre compressions: no box
// should ever be thrown up. Contacts with zero penetration at the start of a step must act
// within that step.
TEST(World, TenBoxStackPlacedTouchingDoesNotBounce) {
  World w;
  ground_plane(w);
  const std::vector<BodyId> boxes = stack(w, 10, 0.25f);
  double vmax = 0, up = 0, sink = 0;
  uint32_t max_islands = 0;
  for (int i = 1; i <= 2 * kHz; ++i) {
    const StepStats& st = w.step();
    if (st.active_bodies == 10) max_islands = std::max(max_islands, st.islands);
    vmax = std::max(vmax, double(max_speed(w, boxes)));
    for (BodyId b : boxes) up = std::max(up, double(w.state(b).velocity[2]));
    sink = std::max(sink, 0.25 + 0.5 * 9 - w.state(boxes.back()).position[2]);
  }
  record("stack_touching_max_speed_mps", vmax);
  record("stack_touching_max_upward_mps", up);
  record("stack_touching_top_sink_m", sink);
  record("stack_touching_max_islands", max_islands);
  // The soft contacts first compress to carry the weight above them (the top box sinks a few
  // mm at about 0.1 m/s in the first two steps) until each pair is stiffened to the load it
  // carries and sinks contact.load_depth (0.1 mm a layer): nothing may move up faster than
  // cm/s, and the stack may not sink by a centimetre.
  EXPECT_LT(up, 0.05) << "a resting stack was thrown up";
  EXPECT_LT(sink, 0.01) << "the stack sank into itself";
  EXPECT_LT(vmax, 0.2) << "a resting stack fell into itself";
  EXPECT_LE(max_islands, 1u) << "the stack came apart into separate islands";
}

TEST(World, TenBoxStackStandsForTenSeconds) {
  World w;
  ground_plane(w);
  // slightly imperfect: odd and even boxes offset by +-2 mm in x and y
  const std::vector<BodyId> boxes = stack(w, 10, 0.25f, 0.0f, 1.0f, nullptr, 0.5f, 0.002f);
  const BodyId top = boxes.back();
  const BodyState s0 = w.state(top);
  double lateral = 0, drop = 0;
  int asleep_at = -1;
  for (int i = 1; i <= 10 * kHz; ++i) {
    const StepStats& st = w.step();
    const BodyState s = w.state(top);
    ASSERT_TRUE(finite_state(s)) << "step " << i;
    ASSERT_EQ(st.failed_islands, 0u) << "step " << i;
    lateral = std::max(lateral, std::hypot(double(s.position[0]) - s0.position[0], double(s.position[1]) - s0.position[1]));
    drop = std::max(drop, double(s0.position[2]) - s.position[2]);
    if (asleep_at < 0 && st.active_bodies == 0) asleep_at = i;
  }
  record("stack_top_lateral_m", lateral);
  record("stack_top_max_drop_m", drop);
  record("stack_asleep_after_s", asleep_at / double(kHz));
  EXPECT_LT(lateral, 0.01) << "top box moved 1 cm or more sideways";
  EXPECT_LT(drop, 0.01) << "top box fell (10 layers compress by ~1.4 mm in all)";
  int off_layer = 0;
  for (size_t k = 0; k < boxes.size(); ++k)
    if (!(std::fabs(w.state(boxes[k]).position[2] - (0.25 + 0.5 * double(k))) < 0.01)) ++off_layer;
  record("stack_boxes_off_their_layer", off_layer);
  EXPECT_EQ(off_layer, 0) << "boxes are not at their layers";
  EXPECT_GT(asleep_at, 0) << "the stack never fell asleep";
}

// ---------------------------------------------------------------------------------------------
// 2. Incline: rolling and sliding against closed forms

TEST(World, SphereRollsDownInclineWithoutSlidingAtFiveSeventhsGSinTheta) {
  const float theta = float(20.0 * kPi / 180.0), r = 0.25f, mu = 0.8f;  // rolls when mu > (2/7) tan(theta) = 0.10
  WorldSettings s;
  s.sleeping = false;
  World w(s);
  const Incline in = incline(w, theta, mu);
  // Resting on the incline at the depth a contact settles to under its load (contact.load_depth),
  // so the contact acts from the first step (a contact that starts at zero depth has its own
  // test above).
  const float m = 1.0f, sink = w.settings().contact_load_depth;
  float p[3];
  point_on_incline(in, 0.0f, r - sink, p);
  const BodyId ball = add_sphere(w, r, m, p, mu);
  std::vector<double> t, v;
  double worst_ratio = 0;
  for (int i = 1; i <= 2 * kHz; ++i) {
    w.step();
    const BodyState st = w.state(ball);
    ASSERT_TRUE(finite_state(st)) << "step " << i;
    if (i >= kHz / 2) {  // after the contact transient
      t.push_back(i / double(kHz));
      v.push_back(dot3(st.velocity, in.downhill));
      const double speed = norm3(st.velocity), spin = norm3(st.angular_velocity) * r;
      worst_ratio = std::max(worst_ratio, std::fabs(speed - spin) / std::max(speed, 1e-9));
    }
  }
  const double a = slope(t, v), expected = 5.0 / 7.0 * kG * std::sin(theta);
  const BodyState end = w.state(ball);
  const double speed = norm3(end.velocity), spin = norm3(end.angular_velocity) * r;
  record("rolling_acceleration", a);
  record("rolling_expected", expected);
  record("rolling_final_speed", speed);
  record("rolling_final_omega_r", spin);
  record("rolling_worst_slip_ratio", worst_ratio);
  EXPECT_NEAR(a, expected, 0.05 * expected);
  EXPECT_NEAR(speed, spin, 0.03 * speed) << "sliding, not rolling";
  // stays on the surface: centre at r above the plane
  EXPECT_NEAR(dot3(end.position, in.normal), r, 2e-3);
}

struct InclineRun {
  double acceleration = 0;  // fitted downhill acceleration over the window
  double max_speed_late = 0;
  double lift = 0;  // largest height of the centre above its resting height
  bool finite = true;
};

// A 1 kg box lying flat on a 20 degree incline, friction mu on both sides; acceleration fitted
// over [t0, t1] s, max speed measured after t0.
InclineRun box_on_incline(float theta, float mu, double t0, double t1) {
  WorldSettings s;
  s.sleeping = false;
  World w(s);
  const Incline in = incline(w, theta, mu);
  float p[3], q[4];
  point_on_incline(in, 0.0f, 0.25f, p);
  incline_orientation(theta, q);
  const float half[3] = {0.25f, 0.25f, 0.25f};
  const BodyId box = add_box(w, half, 1.0f, p, q, mu);
  InclineRun r;
  std::vector<double> t, v;
  for (int i = 1; i <= int(t1 * kHz); ++i) {
    w.step();
    const BodyState st = w.state(box);
    if (!finite_state(st)) {
      r.finite = false;
      return r;
    }
    r.lift = std::max(r.lift, dot3(st.position, in.normal) - 0.25);
    if (i >= int(t0 * kHz)) {
      t.push_back(i / double(kHz));
      v.push_back(dot3(st.velocity, in.downhill));
      r.max_speed_late = std::max(r.max_speed_late, norm3(st.velocity));
    }
  }
  r.acceleration = slope(t, v);
  return r;
}

TEST(World, BoxOnInclineStaysWhenFrictionExceedsTanTheta) {
  const float theta = float(20.0 * kPi / 180.0);  // tan = 0.364
  // The friction anchor holds it (measured 1e-6 m/s); regularised Coulomb friction alone let it
  // creep at s tan(theta) / sqrt(mu^2 - tan^2), 7.6 mm/s with s = 0.01 m/s. The claim allows 1 cm/s;
  // tests/test_contacts.cpp holds creep to 1 mm in 2 s.
  const InclineRun r = box_on_incline(theta, 0.6f, 1.0, 3.0);
  ASSERT_TRUE(r.finite);
  record("incline_held_max_speed_mps", r.max_speed_late);
  record("incline_held_drift_accel", r.acceleration);
  EXPECT_LT(r.max_speed_late, 0.01) << "the box does not stay";
  EXPECT_LT(r.lift, 0.005) << "the box left the surface";
}

TEST(World, BoxOnInclineSlidesAtGTimesSinMinusMuCos) {
  const float theta = float(20.0 * kPi / 180.0), mu = 0.2f;
  const InclineRun r = box_on_incline(theta, mu, 0.5, 1.5);
  ASSERT_TRUE(r.finite);
  const double expected = kG * (std::sin(theta) - mu * std::cos(theta));
  record("incline_slide_acceleration", r.acceleration);
  record("incline_slide_expected", expected);
  EXPECT_NEAR(r.acceleration, expected, 0.02 * expected);
  EXPECT_LT(r.lift, 0.005) << "the box left the surface";
}

// ---------------------------------------------------------------------------------------------
// 3. Closed-form checks of the contact step itself (the defects the scenes above run into)

// A box with a small tilt lands on one corner: a penalty contact may lose energy, never gain it.
TEST(World, CornerImpactDoesNotGainEnergy) {
  for (float mu : {0.0f, 0.5f}) {
    World w;
    ground_plane(w, mu);
    const float tilt = 0.15f, half[3] = {0.25f, 0.25f, 0.25f};
    const float q[4] = {std::cos(0.5f * tilt), 0.6f * std::sin(0.5f * tilt), 0.8f * std::sin(0.5f * tilt), 0.0f};
    const float p[3] = {0.0f, 0.0f, 0.5f};
    const BodyId box = add_box(w, half, 1.0f, p, q, mu);
    // energy at the start (kinetic + potential), relative to the resting height
    auto energy = [&] { return w.kinetic_energy() + 1.0 * kG * (w.state(box).position[2] - 0.25); };
    const double e0 = energy();
    double worst = 0;
    for (int i = 1; i <= kHz; ++i) {
      w.step();
      worst = std::max(worst, w.kinetic_energy());
    }
    record(std::string("corner_impact_mu") + (mu > 0 ? "0.5" : "0") + "_max_kinetic_J", worst);
    record(std::string("corner_impact_mu") + (mu > 0 ? "0.5" : "0") + "_start_energy_J", e0);
    EXPECT_LE(worst, 1.05 * e0) << "mu = " << mu << ": the impact created energy";
  }
}

// A box sliding on the ground at 1 m/s stops in v / (mu g) = 0.2 s and stays stopped.
TEST(World, SlidingBoxComesToRestAndStays) {
  WorldSettings s;
  s.sleeping = false;
  World w(s);
  ground_plane(w);
  const float half[3] = {0.25f, 0.25f, 0.25f}, p[3] = {0.0f, 0.0f, 0.2499f};  // 0.1 mm deep: contact active
  const BodyId box = add_box(w, half, 1.0f, p);
  BodyState st = w.state(box);
  st.velocity[0] = 1.0f;
  w.set_state(box, st);
  double late = 0;
  for (int i = 1; i <= kHz; ++i) {
    w.step();
    if (i > kHz / 2) late = std::max(late, double(max_speed(w)) + 0.25 * max_angular_speed(w));
  }
  record("sliding_box_late_speed_mps", late);
  EXPECT_LT(late, 1e-3) << "the box does not come to rest (friction flip-flop?)";
}

// ---------------------------------------------------------------------------------------------
// 4. The reference scene: 65 boxes into a bin

TEST(World, SeedPileOf65BoxesMakesAbout400ContactsSettlesAndSleeps) {
  World w;
  const std::vector<BodyId> boxes = pile_in_bin(w, 65, 0.25f, 1);
  std::vector<float> dropped_from;
  for (BodyId b : boxes) dropped_from.push_back(w.state(b).position[2]);
  uint32_t settled_contacts = 0, settled_islands = 0, max_contacts = 0;
  double settle_time = -1;
  int asleep_at = -1;
  const int n_steps = 10 * kHz;
  for (int i = 1; i <= n_steps + 2 * kHz; ++i) {
    const StepStats& st = w.step();
    ASSERT_EQ(st.failed_islands, 0u) << "step " << i;
    max_contacts = std::max(max_contacts, st.contacts);
    const float v = max_speed(w, boxes);
    if (st.active_bodies == boxes.size()) {
      settled_contacts = st.contacts, settled_islands = st.islands;  // the last all-awake step
      if (v < 0.05f && settle_time < 0) settle_time = i / double(kHz);
      if (v >= 0.05f) settle_time = -1;
    }
    if (i == n_steps) {
      record("pile65_max_speed_at_10s", v);
      EXPECT_LT(v, 0.05f) << "the pile has not settled after 10 s";
    }
    if (st.active_bodies == 0 && asleep_at < 0) asleep_at = i;
    if (i >= n_steps && asleep_at > 0) break;
  }
  record("pile65_contacts_settled", settled_contacts);
  record("pile65_islands_settled", settled_islands);
  record("pile65_max_contacts", max_contacts);
  record("pile65_settled_after_s", settle_time);
  record("pile65_asleep_after_s", asleep_at / double(kHz));
  EXPECT_GE(settled_contacts, 250u);
  EXPECT_LE(settled_contacts, 600u);
  EXPECT_GT(asleep_at, 0) << "the pile never fell asleep";
  // Left the bin, sank through the floor or rest higher than they were dropped from (thrown
  // up). The columns of the drop grid stack neatly, so the 65th box may rest on a column of 4
  // above the walls' top: that is in place.
  int outside = 0;
  for (size_t k = 0; k < boxes.size(); ++k) {
    const BodyState s = w.state(boxes[k]);
    const float hb = bin_half_width(65, 0.25f);
    if (!finite_state(s) || std::fabs(s.position[0]) > hb || std::fabs(s.position[1]) > hb || s.position[2] < 0.2f ||
        s.position[2] > dropped_from[k])
      ++outside;
  }
  record("pile65_boxes_out_of_place", outside);
  EXPECT_EQ(outside, 0) << "boxes left the bin";
}

// ---------------------------------------------------------------------------------------------
// 5. A sparse 1,000-body world: most of it sleeps, and then costs almost nothing

TEST(World, SparseWorldOfThousandBodiesMostlySleepsAndCostFollowsActiveBodies) {
  World w;
  const std::vector<BodyId> bodies = sparse_world(w, 1000, 100.0f, 1);
  ASSERT_EQ(bodies.size(), 1000u);
  // windows: the first third of a second (everything awake: nothing sleeps before 0.5 s) and
  // the last second
  const int n_steps = 10 * kHz, first_window = kHz / 3, last_window = kHz;
  std::vector<double> first_t, last_t;
  std::vector<uint32_t> first_active, last_active, first_islands, last_islands;
  uint32_t failed = 0;
  for (int i = 1; i <= n_steps; ++i) {
    const StepStats& st = w.step();
    failed += st.failed_islands;
    const double work = st.times.pack_ms + st.times.integrate_ms;
    if (i <= first_window) first_t.push_back(work), first_active.push_back(st.active_bodies), first_islands.push_back(st.islands);
    if (i > n_steps - last_window) last_t.push_back(work), last_active.push_back(st.active_bodies), last_islands.push_back(st.islands);
  }
  const int asleep = count_asleep(w, bodies);
  const double t_first = median(first_t), t_last = median(last_t);
  record("sparse_asleep_fraction", asleep / 1000.0);
  record("sparse_first_active", first_active.front());
  record("sparse_first_islands", first_islands.front());
  record("sparse_last_active", last_active.back());
  record("sparse_last_islands", last_islands.back());
  record("sparse_first_pack_integrate_ms_median", t_first);
  record("sparse_last_pack_integrate_ms_median", t_last);
  record("sparse_failed_islands_total", failed);
  EXPECT_GT(asleep, 900) << "fewer than 90% asleep after 10 s";
  EXPECT_EQ(failed, 0u);
  // Work counters: a few islands and bodies left to integrate at the end.
  EXPECT_LT(last_active.back(), first_active.front() / 10);
  EXPECT_LT(last_islands.back(), first_islands.front() / 10);
  // Time: per-step medians over the windows (robust to a descheduled step); pack + integrate
  // in the last second is a small fraction of the first steps'.
  EXPECT_LT(t_last, 0.3 * t_first);
  // and nothing flew away
  float highest = 0;
  for (BodyId b : bodies) highest = std::max(highest, w.state(b).position[2]);
  record("sparse_highest_body_m", highest);
  EXPECT_LT(highest, 2.0f) << "a body was thrown into the air";
}

// ---------------------------------------------------------------------------------------------
// 6. Islands

TEST(World, IslandsOfKnownScenes) {
  {  // three separate stacks of three on one ground: the ground joins nothing
    World w;
    ground_plane(w);
    for (int k = 0; k < 3; ++k) {
      const float base[3] = {3.0f * float(k), 0.0f, 0.0f};
      stack(w, 3, 0.25f, 0.0f, 1.0f, base);
    }
    const StepStats& st = w.step();
    EXPECT_EQ(st.islands, 3u) << "three stacks";
    EXPECT_EQ(st.active_bodies, 9u);
  }
  {  // two boxes on the ground, apart: two islands
    World w;
    ground_plane(w);
    const float h[3] = {0.25f, 0.25f, 0.25f}, a[3] = {0, 0, 0.25f}, b[3] = {2, 0, 0.25f};
    const BodyId x = add_box(w, h, 1.0f, a), y = add_box(w, h, 1.0f, b);
    EXPECT_EQ(w.step().islands, 2u) << "a static ground does not join islands";
    // last_island names each body's island in the step; a body added since has none yet
    EXPECT_LT(w.last_island(x), 2u);
    EXPECT_LT(w.last_island(y), 2u);
    EXPECT_NE(w.last_island(x), w.last_island(y));
    const float c[3] = {4, 0, 0.25f};
    const BodyId z = add_box(w, h, 1.0f, c);
    EXPECT_EQ(w.last_island(z), ppe::kNoIsland);
    w.remove_body(x);
    EXPECT_EQ(w.step().islands, 2u);
    EXPECT_THROW(w.last_island(x), WorldError) << "a removed body";
    EXPECT_LT(w.last_island(z), 2u);
    EXPECT_NE(w.last_island(y), w.last_island(z));
  }
  {  // two boxes in the air joined by a point_to_point: one island; without it, two
    for (bool joined : {true, false}) {
      World w;
      const float h[3] = {0.25f, 0.25f, 0.25f}, a[3] = {0, 0, 5}, b[3] = {1, 0, 5};
      const BodyId x = add_box(w, h, 1.0f, a), y = add_box(w, h, 1.0f, b);
      if (joined)
        w.add_force("point_to_point", x, y, {{"point_a", {0.5f, 0, 0}}, {"point_b", {-0.5f, 0, 0}}, {"stiffness", {1e4f}}});
      EXPECT_EQ(w.step().islands, joined ? 1u : 2u) << (joined ? "joined" : "apart");
    }
  }
  {  // a 6-link chain pinned to the world: one island (the world anchor is not a body)
    World w;
    chain(w, 6);
    EXPECT_EQ(w.step().islands, 1u);
  }
  {  // a unary force (world-anchored spring) does not join two bodies
    World w;
    const float h[3] = {0.25f, 0.25f, 0.25f}, a[3] = {0, 0, 5}, b[3] = {1, 0, 5};
    const BodyId x = add_box(w, h, 1.0f, a);
    add_box(w, h, 1.0f, b);
    w.add_force("spring", x, ppe::kWorldBody, {{"point_b", {0, 0, 6}}, {"stiffness", {10.0f}}});
    EXPECT_EQ(w.step().islands, 2u);
  }
}

// ---------------------------------------------------------------------------------------------
// 7. Decoupling: a 300-box pile does not fit one local store

// A stack cut into parts of one or two boxes (a 16 KiB local store) stands as the whole one
// does: the parts run in order, each holding its neighbours as kinematic ghosts.
TEST(World, DecoupledStackStandsAndSleepsLikeTheWholeOne) {
  WorldSettings s;
  s.local_store_bytes = 16 * 1024;
  s.whole_island_bytes = 0;  // split, not computed whole
  World w(s);
  ground_plane(w);
  const std::vector<BodyId> boxes = stack(w, 10, 0.25f);
  uint32_t decoupled = 0, max_cut = 0;
  double vmax = 0;
  int asleep_at = -1;
  for (int i = 1; i <= 2 * kHz; ++i) {
    const StepStats& st = w.step();
    ASSERT_EQ(st.failed_islands, 0u) << "step " << i;
    decoupled += st.decoupled_islands;
    max_cut = std::max(max_cut, st.cut_couplings);
    vmax = std::max(vmax, double(max_speed(w, boxes)));
    if (asleep_at < 0 && st.active_bodies == 0) asleep_at = i;
  }
  record("decoupled_stack_max_speed_mps", vmax);
  record("decoupled_stack_max_cut_couplings", max_cut);
  record("decoupled_stack_asleep_after_s", asleep_at / double(kHz));
  EXPECT_GT(decoupled, 0u) << "the stack was never cut";
  EXPECT_LT(vmax, 0.05) << "a cut stack was thrown about (the whole one moves < 0.05 m/s)";
  EXPECT_GT(asleep_at, 0) << "the cut stack never fell asleep";
  EXPECT_NEAR(w.state(boxes.back()).position[2], 0.25 + 0.5 * 9, 0.01);
}

// A split island whose parts cannot step (an adaptive step at an unreachable tolerance, no
// halving) is one failed island, reported once per step however many parts and sweeps it
// took; it keeps its start pose and is stopped (integrators.md: kept moving, a ragdoll whose
// step failed failed again from the same state every step, frozen in the air at 6.7 m/s).
TEST(World, SplitIslandThatFailsKeepsItsPoseStopsAndCountsOnce) {
  WorldSettings s;
  s.local_store_bytes = 16 * 1024;
  s.whole_island_bytes = 0;
  s.integrator = cellphys::spu::Integrator::rosenbrock;
  s.tolerance = 1e-30f;
  s.max_halvings = 0;
  World w(s);
  ground_plane(w);
  const std::vector<BodyId> boxes = stack(w, 10, 0.25f, 0.01f);  // 1 cm gaps: falling, not at rest
  for (BodyId b : boxes) {
    BodyState st = w.state(b);
    st.velocity[2] = -0.5f;
    w.set_state(b, st);
  }
  std::vector<BodyState> before;
  for (BodyId b : boxes) before.push_back(w.state(b));
  const StepStats& st = w.step();
  ASSERT_GT(st.decoupled_islands, 0u);
  EXPECT_EQ(st.failed_islands, 1u) << "sweeps " << st.decouple_sweeps;
  for (size_t k = 0; k < boxes.size(); ++k) {
    const BodyState now = w.state(boxes[k]);
    for (int c = 0; c < 3; ++c) {
      EXPECT_EQ(now.position[c], before[k].position[c]) << "box " << k;
      EXPECT_EQ(now.velocity[c], 0.0f) << "box " << k;
      EXPECT_EQ(now.angular_velocity[c], 0.0f) << "box " << k;
    }
    for (int c = 0; c < 4; ++c) EXPECT_EQ(now.orientation[c], before[k].orientation[c]) << "box " << k;
  }
}

TEST(World, PileOf300BoxesIsDecoupledToFitTheLocalStoreAndSettles) {
  WorldSettings s;
  s.whole_island_bytes = 0;  // split into parts that fit, as the reference design does
  World w(s);
  const std::vector<BodyId> boxes = pile_in_bin(w, 300, 0.25f, 1);
  const size_t capacity = w.settings().local_store_bytes;
  uint32_t decoupled_steps = 0, max_cut = 0, max_parts_islands = 0, failed = 0, max_sweeps = 0;
  size_t peak = 0;
  const int n_steps = 5 * kHz;
  for (int i = 1; i <= n_steps; ++i) {
    const StepStats& st = w.step();
    failed += st.failed_islands;
    peak = std::max(peak, st.local_store_peak_bytes);
    if (st.decoupled_islands > 0) ++decoupled_steps;
    max_cut = std::max(max_cut, st.cut_couplings);
    max_parts_islands = std::max(max_parts_islands, st.decoupled_islands);
    max_sweeps = std::max(max_sweeps, st.decouple_sweeps);
  }
  const float v = max_speed(w, boxes);
  record("pile300_decoupled_steps", decoupled_steps);
  record("pile300_max_cut_couplings", max_cut);
  record("pile300_max_sweeps", max_sweeps);
  record("pile300_local_store_peak_bytes", double(peak), 7);
  record("pile300_failed_islands_total", failed);
  record("pile300_max_speed_at_5s", v);
  EXPECT_GT(decoupled_steps, 0u) << "the pile was never decoupled";
  EXPECT_GT(max_cut, 0u);
  EXPECT_EQ(failed, 0u);
  EXPECT_LE(peak, capacity);
  EXPECT_LE(peak, size_t(256 * 1024));
  EXPECT_LT(v, 0.1f) << "the decoupled pile has not settled after 5 s";
}

// The same pile with the default settings: its island, too big for the local store, is computed
// whole in a store grown to fit it (never split), settles, and gives the same bits on two
// workers as on one.
TEST(World, PileOf300BoxesTooBigForTheLocalStoreIsComputedWholeAndSettles) {
  WorldSettings s1, s2;
  s2.workers = 2;
  World w(s1), w2(s2);
  const std::vector<BodyId> boxes = pile_in_bin(w, 300, 0.25f, 1);
  pile_in_bin(w2, 300, 0.25f, 1);
  const size_t capacity = w.settings().local_store_bytes;
  uint32_t decoupled = 0, failed = 0;
  size_t peak = 0;
  for (int i = 1; i <= 5 * kHz; ++i) {
    const StepStats& st = w.step();
    w2.step();
    ASSERT_EQ(w.state_hash(), w2.state_hash()) << "step " << i;
    failed += st.failed_islands;
    decoupled += st.decoupled_islands;
    peak = std::max(peak, st.local_store_peak_bytes);
  }
  const float v = max_speed(w, boxes);
  record("pile300_whole_local_store_peak_bytes", double(peak), 7);
  record("pile300_whole_max_speed_at_5s", v);
  EXPECT_EQ(decoupled, 0u);
  EXPECT_GT(peak, capacity) << "the pile fitted the local store: nothing was computed whole";
  EXPECT_EQ(failed, 0u);
  EXPECT_LT(v, 0.1f) << "the pile has not settled after 5 s";
}

// ---------------------------------------------------------------------------------------------
// 8. Determinism: the outcome does not depend on the number of workers

TEST(World, OneAndTwoWorkersGiveBitIdenticalTrajectories) {
  WorldSettings s1, s2;
  s1.workers = 1;
  s2.workers = 2;
  World a(s1), b(s2), c(s1);
  pile_in_bin(a, 65, 0.25f, 1);
  pile_in_bin(b, 65, 0.25f, 1);
  pile_in_bin(c, 65, 0.25f, 1);
  ASSERT_EQ(a.state_hash(), b.state_hash());
  uint32_t max_islands = 0;
  for (int i = 1; i <= 2 * kHz; ++i) {
    max_islands = std::max(max_islands, a.step().islands);
    b.step();
    c.step();
    ASSERT_EQ(a.state_hash(), b.state_hash()) << "1 and 2 workers differ at step " << i;
    ASSERT_EQ(a.state_hash(), c.state_hash()) << "two runs with 1 worker differ at step " << i;
  }
  char hex[32];
  std::snprintf(hex, sizeof hex, "%016llx", static_cast<unsigned long long>(a.state_hash()));
  record("pile65_state_hash_after_2s", hex);
  record("pile65_max_islands_first_2s", max_islands);
  EXPECT_GT(max_islands, 1u) << "no step had more than one island: the workers had nothing to share";
}

// ---------------------------------------------------------------------------------------------
// 9. Bad input is refused and changes nothing

std::string what_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const WorldError& e) {
    return std::string("WorldError: ") + e.what();
  } catch (const ShapeError& e) {
    return std::string("ShapeError: ") + e.what();
  }
  return "(nothing thrown)";
}

bool has(const std::string& s, const std::string& part) { return s.find(part) != std::string::npos; }

TEST(World, BadInputIsRefusedClearlyAndChangesNothing) {
  // Two identical worlds; one receives every bad call. Afterwards both step to the same bits.
  auto build = [](World& w) {
    ground_plane(w);
    return stack(w, 2, 0.25f);
  };
  World w, twin;
  const std::vector<BodyId> ids = build(w);
  build(twin);
  const size_t n0 = w.num_bodies(), shapes0 = w.shapes().size();
  const uint64_t h0 = w.state_hash();
  const uint32_t box_shape = 1;  // the stack's box (shape 0 is the plane)
  auto unchanged = [&](const std::string& what) {
    EXPECT_EQ(w.num_bodies(), n0) << what;
    EXPECT_EQ(w.state_hash(), h0) << what;
    EXPECT_EQ(w.shapes().size(), shapes0) << what;
  };
  auto body = [&] {
    BodyDesc d;
    d.shape = box_shape;
    d.mass = 1.0f;
    d.state.position[2] = 3.0f;
    return d;
  };
  const float nan = std::numeric_limits<float>::quiet_NaN();
  struct Case {
    std::string name, expect;
    std::function<void()> call;
  };
  std::vector<Case> cases = {
      {"negative mass", "mass must be positive", [&] { BodyDesc d = body(); d.mass = -1.0f; w.add_body(d); }},
      {"no mass, no density", "positive mass or density", [&] { BodyDesc d = body(); d.mass = 0.0f; w.add_body(d); }},
      {"negative density", "positive mass or density", [&] { BodyDesc d = body(); d.mass = 0.0f; d.density = -5.0f; w.add_body(d); }},
      {"NaN mass", "mass must be positive", [&] { BodyDesc d = body(); d.mass = nan; w.add_body(d); }},
      {"zero scale", "scale must be positive", [&] { BodyDesc d = body(); d.scale = 0.0f; w.add_body(d); }},
      {"negative scale", "scale must be positive", [&] { BodyDesc d = body(); d.scale = -1.0f; w.add_body(d); }},
      {"NaN position", "finite", [&] { BodyDesc d = body(); d.state.position[1] = nan; w.add_body(d); }},
      {"infinite velocity", "finite", [&] { BodyDesc d = body(); d.state.velocity[0] = std::numeric_limits<float>::infinity(); w.add_body(d); }},
      {"zero quaternion", "zero quaternion", [&] { BodyDesc d = body(); d.state.orientation[0] = 0.0f; w.add_body(d); }},
      {"unknown shape", "does not exist", [&] { BodyDesc d = body(); d.shape = 99; w.add_body(d); }},
      {"negative friction", "friction", [&] { BodyDesc d = body(); d.friction = -0.1f; w.add_body(d); }},
      {"force on a missing body", "does not exist",
       [&] { w.add_force("spring", ids[0], 999, {{"stiffness", {10.0f}}}); }},
      {"force from a missing body", "does not exist",
       [&] { w.add_force("spring", 999, ppe::kWorldBody, {{"stiffness", {10.0f}}}); }},
      {"unknown force type", "unknown force type", [&] { w.add_force("glue", ids[0], ids[1], {}); }},
      {"unknown parameter", "unknown parameter 'stifness'",
       [&] { w.add_force("spring", ids[0], ids[1], {{"stifness", {10.0f}}}); }},
      {"wrong parameter width", "takes 3 number", [&] { w.add_force("spring", ids[0], ids[1], {{"point_a", {1.0f}}}); }},
      {"negative stiffness", "must be >=", [&] { w.add_force("spring", ids[0], ids[1], {{"stiffness", {-1.0f}}}); }},
      {"force on itself", "same body", [&] { w.add_force("spring", ids[0], ids[0], {}); }},
      {"force on the static ground", "static", [&] { w.add_force("spring", 0, ids[0], {}); }},
      {"state of a missing body", "does not exist", [&] { w.state(999); }},
      {"NaN state", "finite",
       [&] { BodyState s = w.state(ids[1]); s.velocity[2] = nan; w.set_state(ids[1], s); }},
      {"zero quaternion state", "zero quaternion",
       [&] { BodyState s = w.state(ids[1]); std::fill(s.orientation, s.orientation + 4, 0.0f); w.set_state(ids[1], s); }},
      {"impulse on a static body", "static",
       [&] { const float j[3] = {1, 0, 0}, p[3] = {0, 0, 0}; w.apply_impulse(0, j, p); }},
      {"NaN impulse", "finite",
       [&] { const float j[3] = {nan, 0, 0}, p[3] = {0, 0, 0}; w.apply_impulse(ids[1], j, p); }},
      {"degenerate hull: 3 points", "hull",
       [&] { const float p[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0}; w.shapes().add_hull(p, 3); }},
      {"degenerate hull: coplanar", "hull",
       [&] { const float p[15] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0, 0.5f, 0.5f, 0}; w.shapes().add_hull(p, 5); }},
      {"degenerate hull: collinear", "hull",
       [&] { const float p[12] = {0, 0, 0, 1, 1, 1, 2, 2, 2, 3, 3, 3}; w.shapes().add_hull(p, 4); }},
      {"negative sphere radius", "sphere", [&] { w.shapes().add_sphere(-1.0f); }},
      {"zero box extent", "box", [&] { const float h[3] = {1, 0, 1}; w.shapes().add_box(h); }},
      {"zero plane normal", "plane: normal is zero", [&] { const float n[3] = {0, 0, 0}; w.shapes().add_plane(n, 0.0f); }},
  };
  for (const Case& c : cases) {
    const std::string msg = what_of(c.call);
    std::string key = "refusal_" + c.name;
    for (char& ch : key)
      if (!std::isalnum(static_cast<unsigned char>(ch))) ch = '_';
    record(key, msg);
    const bool is_error = has(msg, "WorldError: ") || has(msg, "ShapeError: ");
    EXPECT_TRUE(is_error) << c.name << ": " << msg;
    if (has(c.name, "hull") || has(c.name, "sphere") || has(c.name, "box extent") || has(c.name, "plane normal")) {
      EXPECT_TRUE(has(msg, "ShapeError: ")) << c.name << ": " << msg;
    }
    EXPECT_TRUE(has(msg, c.expect)) << c.name << ": message '" << msg << "' does not say '" << c.expect << "'";
    unchanged(c.name);
  }
  // A non-unit quaternion is accepted, normalised, and says so.
  BodyDesc d = body();
  d.state.orientation[0] = 2.0f;
  const BodyId extra = w.add_body(d);
  ASSERT_FALSE(w.warnings().empty()) << "no warning for a non-unit quaternion";
  EXPECT_TRUE(has(w.warnings().front(), "normalised")) << w.warnings().front();
  EXPECT_FLOAT_EQ(w.state(extra).orientation[0], 1.0f);
  w.remove_body(extra);
  EXPECT_EQ(w.num_bodies(), n0);
  EXPECT_EQ(w.state_hash(), h0);
  // The world that saw every refusal steps exactly as its twin.
  for (int i = 0; i < 30; ++i) {
    w.step();
    twin.step();
  }
  EXPECT_EQ(w.state_hash(), twin.state_hash()) << "a refused call left something behind";
}

// ---------------------------------------------------------------------------------------------
// 10. Sleeping and waking

// Steps until every body of the world sleeps (at most max_steps); returns the steps taken or -1.
int run_until_asleep(World& w, int max_steps) {
  for (int i = 1; i <= max_steps; ++i)
    if (w.step().active_bodies == 0) return i;
  return -1;
}

TEST(World, SleepingStackCostsNothingAndWakesWhenHitPushedOrForced) {
  World w;
  ground_plane(w);
  const std::vector<BodyId> tower = stack(w, 3, 0.25f);
  const float far[3] = {10.0f, 0.0f, 0.2f};
  const BodyId ball = add_sphere(w, 0.2f, 2.0f, far);  // resting on the ground, far away
  auto all_awake = [&] {
    for (BodyId b : tower)
      if (!w.is_awake(b)) return false;
    return true;
  };
  auto all_asleep = [&] {
    for (BodyId b : tower)
      if (w.is_awake(b)) return false;
    return true;
  };

  const int first_sleep = run_until_asleep(w, 5 * kHz);
  record("sleep_first_after_s", first_sleep / double(kHz));
  ASSERT_GT(first_sleep, 0) << "the stack and ball never fell asleep";
  for (int i = 0; i < 10; ++i) {  // asleep: no integration work at all
    const StepStats& st = w.step();
    EXPECT_EQ(st.active_bodies, 0u);
    EXPECT_EQ(st.islands, 0u);
    EXPECT_EQ(st.solver_iterations, 0u);
    EXPECT_EQ(st.contacts, 0u);
    EXPECT_EQ(st.sleeping_bodies, 4u);
  }
  const BodyState rest = w.state(tower.back());

  // (a) a ball dropped on it wakes it
  BodyState b = w.state(ball);
  b.position[0] = 0.0f, b.position[1] = 0.0f, b.position[2] = 2.5f;
  b.velocity[2] = -3.0f;
  w.set_state(ball, b);
  EXPECT_TRUE(w.is_awake(ball));
  EXPECT_TRUE(all_asleep()) << "moving the ball woke the stack before it touched";
  bool woke = false;
  uint32_t woken = 0;
  for (int i = 0; i < kHz && !woke; ++i) {
    woken += w.step().woken;
    woke = all_awake();
  }
  EXPECT_TRUE(woke) << "the ball's hit did not wake the stack";
  EXPECT_GT(woken, 0u);
  record("wake_by_hit_top_moved_m", dist3(w.state(tower.back()).position, rest.position));
  w.remove_body(ball);  // a ball left rolling would keep the world awake: the rest is about the stack

  // (b) a force on one of its bodies wakes it, at once
  const int after_hit = run_until_asleep(w, 10 * kHz);
  record("sleep_after_hit_s", after_hit / double(kHz));
  ASSERT_GT(after_hit, 0) << "the stack did not fall asleep again after the hit";
  const ppe::ForceId f =
      w.add_force("spring", tower[1], ppe::kWorldBody, {{"point_b", {0, 0, 0.75f}}, {"stiffness", {1.0f}}});
  EXPECT_TRUE(all_awake()) << "add_force did not wake the stack";
  EXPECT_GT(w.step().active_bodies, 0u);
  w.remove_force(f);

  // (c) an impulse wakes it, at once
  const int after_force = run_until_asleep(w, 10 * kHz);
  record("sleep_after_force_s", after_force / double(kHz));
  ASSERT_GT(after_force, 0) << "the stack did not fall asleep again after the force";
  const float j[3] = {0.2f, 0.0f, 0.0f};
  const BodyState top = w.state(tower.back());
  w.apply_impulse(tower.back(), j, top.position);
  EXPECT_TRUE(all_awake()) << "apply_impulse did not wake the stack";
  EXPECT_NEAR(w.state(tower.back()).velocity[0], 0.2f, 1e-6f);
  EXPECT_GT(w.step().active_bodies, 0u);
}

}  // namespace

