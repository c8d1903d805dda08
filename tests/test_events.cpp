// Contact and sensor events (World::contact_events, World::sensor_events; docs/events.md): one
// begin per landing with the speed it had and the impulse that stopped it (against free fall's
// closed form, several shapes, masses and heights), no flicker while a body rests or sleeps, an
// end where a body rolls off, sensors that see a body come and go without touching it, removed
// bodies' ends, and a restored snapshot that carries on with the same events.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "runtime/ppe/world.h"

namespace {

using namespace cellphys::ppe;

constexpr double kG = 9.81;
using Kind = ContactEvent::Kind;

BodyId add_ground(World& w) {
  const float up[3] = {0, 0, 1};
  BodyDesc d;
  d.shape = w.shapes().add_plane(up, 0.0f);
  d.is_static = true;
  return w.add_body(d);
}

BodyId add_static_box(World& w, const float half[3], const float pos[3], bool sensor = false) {
  BodyDesc d;
  d.shape = w.shapes().add_box(half);
  d.is_static = true;
  d.sensor = sensor;
  std::copy(pos, pos + 3, d.state.position);
  return w.add_body(d);
}

enum class Shape { sphere, box, capsule };
const char* name_of(Shape s) { return s == Shape::sphere ? "sphere" : s == Shape::box ? "box" : "capsule"; }

// A body of `size` (radius or half side) with its lowest point at `bottom` above z = 0.
BodyId drop(World& w, Shape shape, float size, float mass, float bottom, float vx = 0) {
  BodyDesc d;
  const float half[3] = {size, size, size};
  d.shape = shape == Shape::sphere ? w.shapes().add_sphere(size)
            : shape == Shape::box  ? w.shapes().add_box(half)
                                   : w.shapes().add_capsule(size, size);
  const float lowest = shape == Shape::capsule ? 2 * size : size;  // a capsule stands on its axis
  d.mass = mass;
  d.state.position[2] = bottom + lowest;
  d.state.velocity[0] = vx;
  return w.add_body(d);
}

std::vector<ContactEvent> of_pair(const std::vector<ContactEvent>& events, BodyId x, BodyId y) {
  std::vector<ContactEvent> out;
  for (const ContactEvent& e : events)
    if (e.a == std::min(x, y) && e.b == std::max(x, y)) out.push_back(e);
  return out;
}

struct Landing {
  int begins = 0, ends = 0, late = 0;  // late: events once it should rest (after 2 s)
  double speed_before = 0;             // the body's speed at the start of its first touch's step
  double speed_after = 0;              // and at its end
  double height_before = 0;            // its centre's height at that start, above where it rests
  ContactEvent first{};
};

// Steps the world for `seconds`, collecting the events of (body, ground).
Landing watch(World& w, BodyId body, BodyId ground, double seconds) {
  Landing l;
  const int steps = int(std::lround(seconds / w.settings().dt));
  for (int s = 0; s < steps; ++s) {
    const double speed = std::fabs(w.state(body).velocity[2]), z = w.state(body).position[2];
    w.step();
    for (const ContactEvent& e : of_pair(w.contact_events(), body, ground)) {
      l.late += s * w.settings().dt > 2.0;
      if (e.kind == Kind::end) {
        ++l.ends;
        continue;
      }
      if (++l.begins == 1) l.first = e, l.speed_before = speed, l.height_before = z, l.speed_after = std::fabs(w.state(body).velocity[2]);
    }
  }
  l.height_before -= w.state(body).position[2];
  return l;
}

struct DropCase {
  Shape shape;
  float size, mass, height;
};

class Drops : public ::testing::TestWithParam<DropCase> {};

// A landing begins once, in the step the ground's contact first acts: with the speed of the fall
// (the closed form sqrt(2 g h), to the step's rounding of the moment) and the impulse that stops
// it, the inelastic landing's m (v + g h) (the step's, and what stops the speed it arrives at the
// ground with in that step: docs/events.md). Once the body rests nothing flickers: no event in
// its last 2 s, asleep at the end.
TEST_P(Drops, BeginWithTheFallsSpeedAndImpulseThenNoFlicker) {
  const DropCase c = GetParam();
  SCOPED_TRACE(std::string(name_of(c.shape)) + " size " + std::to_string(c.size) + " mass " + std::to_string(c.mass) +
               " height " + std::to_string(c.height));
  World w;
  const BodyId ground = add_ground(w);
  const BodyId body = drop(w, c.shape, c.size, c.mass, c.height);
  const Landing l = watch(w, body, ground, 4.0);
  EXPECT_EQ(1, l.begins);
  EXPECT_EQ(0, l.ends);
  EXPECT_EQ(0, l.late);
  EXPECT_FALSE(w.is_awake(body)) << "it should rest and sleep within 4 s";
  const double v = std::sqrt(2 * kG * c.height), mv = c.mass * l.speed_before;
  EXPECT_NEAR(l.first.approach_speed, v, kG / 60 + 0.02 * v);
  EXPECT_NEAR(l.first.approach_speed, l.speed_before, 1e-3 * (1 + l.speed_before));
  EXPECT_NEAR(l.first.impulse, mv + c.mass * kG / 60, 0.02 * mv);
  EXPECT_NEAR(l.first.normal[2], 1.0, 1e-5) << "from the lower id (the ground) to the body: up";
  EXPECT_NEAR(l.first.point[2], 0.0, l.speed_before / 60 + 0.02);
  ::testing::Test::RecordProperty("first_impulse_over_mv", std::to_string(l.first.impulse / mv));
  ::testing::Test::RecordProperty("begins", l.begins);
  // Where the body is when its contact first acts, and how fast it goes at that step's end: it
  // arrives at the ground then (docs/events.md).
  ::testing::Test::RecordProperty("height_above_rest_at_begin_m", std::to_string(l.height_before));
  ::testing::Test::RecordProperty("speed_after_begin_step", std::to_string(l.speed_after));
}

INSTANTIATE_TEST_SUITE_P(ShapesMassesHeights, Drops,
                         ::testing::Values(DropCase{Shape::sphere, 0.25f, 1.0f, 1.0f},
                                           DropCase{Shape::sphere, 0.5f, 80.0f, 2.0f},
                                           DropCase{Shape::sphere, 0.3f, 20.0f, 6.0f},
                                           DropCase{Shape::box, 0.5f, 10.0f, 0.5f},
                                           DropCase{Shape::box, 0.1f, 0.5f, 3.0f},
                                           DropCase{Shape::capsule, 0.2f, 5.0f, 1.5f}));

// A ball rolled off a static platform: the platform's touch ends, then the ground's begins.
TEST(ContactEvents, RollingOffAnEdgeEndsOneTouchAndBeginsTheNext) {
  World w;
  const BodyId ground = add_ground(w);
  const float half[3] = {1.0f, 1.0f, 0.25f}, at[3] = {0, 0, 0.25f};
  const BodyId platform = add_static_box(w, half, at);
  const BodyId ball = drop(w, Shape::sphere, 0.2f, 2.0f, 0.5f, 1.5f);
  std::vector<std::string> order;
  for (int s = 0; s < 180; ++s) {
    w.step();
    for (const ContactEvent& e : w.contact_events())
      order.push_back(std::string(e.kind == Kind::begin ? "begin " : "end ") + (std::max(e.a, e.b) == ball && std::min(e.a, e.b) == platform ? "platform" : "ground"));
  }
  const std::vector<std::string> want = {"begin platform", "end platform", "begin ground"};
  EXPECT_EQ(want, order);
  (void)ground;
}

// A static sensor a ball falls through: in while they overlap (where each step's collision sees
// them, at the step's start), out after; the ball falls as if the sensor were not there, bit for
// bit.
TEST(SensorEvents, ABodyFallingThroughIsSeenInThenOutAndNotTouched) {
  for (const float size : {0.1f, 0.4f}) {
    World w, free;
    const float half[3] = {1.0f, 1.0f, 0.5f}, at[3] = {0, 0, 3.0f};
    const BodyId sensor = add_static_box(w, half, at, true);
    const BodyId ball = drop(w, Shape::sphere, size, 3.0f, 5.0f);
    const BodyId free_ball = drop(free, Shape::sphere, size, 3.0f, 5.0f);
    int in_at = -1, out_at = -1;
    for (int s = 0; s < 90; ++s) {
      const float z = w.state(ball).position[2];  // where the step's collision sees it
      w.step();
      free.step();
      const BodyState b = w.state(ball), f = free.state(free_ball);
      for (int k = 0; k < 3; ++k) ASSERT_EQ(f.position[k], b.position[k]) << "step " << s;
      for (const SensorEvent& e : w.sensor_events()) {
        EXPECT_EQ(sensor, e.sensor);
        EXPECT_EQ(ball, e.visitor);
        (e.kind == SensorEvent::Kind::begin ? in_at : out_at) = s;
      }
      const bool overlapping = z - size < 3.5f && z + size > 2.5f;
      EXPECT_EQ(overlapping, w.sensor_contents(sensor) == std::vector<BodyId>{ball}) << "step " << s << " z " << z;
      EXPECT_TRUE(w.contact_events().empty());
    }
    EXPECT_GE(in_at, 0);
    EXPECT_GT(out_at, in_at);
  }
}

// A ray passes through a sensor to what is behind it, unless the query asks for sensors.
TEST(SensorEvents, QueriesPassThroughSensorsUnlessAsked) {
  World w;
  const BodyId ground = add_ground(w);
  const float half[3] = {1.0f, 1.0f, 1.0f}, at[3] = {0, 0, 2.0f};
  const BodyId sensor = add_static_box(w, half, at, true);
  const float from[3] = {0, 0, 10}, down[3] = {0, 0, -1};
  const auto past = w.ray_cast(from, down, 20.0f);
  ASSERT_TRUE(past.has_value());
  EXPECT_EQ(ground, past->body);
  QueryFilter with_sensors;
  with_sensors.sensors = true;
  const auto hit = w.ray_cast(from, down, 20.0f, with_sensors);
  ASSERT_TRUE(hit.has_value());
  EXPECT_EQ(sensor, hit->body);
  EXPECT_NEAR(hit->distance, 7.0f, 1e-4f);
  const float centre[3] = {0, 0, 2.0f};
  EXPECT_TRUE(w.overlap_sphere(centre, 0.5f).empty());
  EXPECT_EQ(std::vector<BodyId>{sensor}, w.overlap_sphere(centre, 0.5f, with_sensors));
}

// A body asleep inside a sensor stays inside and asleep; removing it ends its overlap and its
// touch with the ground in the next step; two sensors do not see each other.
TEST(SensorEvents, SleepersStayInsideAndRemovalEndsEverything) {
  World w;
  const BodyId ground = add_ground(w);
  const float half[3] = {2.0f, 2.0f, 1.0f}, at[3] = {0, 0, 1.0f};
  const BodyId sensor = add_static_box(w, half, at, true);
  const BodyId other = add_static_box(w, half, at, true);
  const BodyId box = drop(w, Shape::box, 0.3f, 4.0f, 0.0f);
  int sensor_begins = 0, sensor_ends = 0;
  for (int s = 0; s < 180; ++s) {
    w.step();
    for (const SensorEvent& e : w.sensor_events()) {
      EXPECT_EQ(box, e.visitor);
      (e.kind == SensorEvent::Kind::begin ? sensor_begins : sensor_ends)++;
    }
  }
  EXPECT_EQ(2, sensor_begins) << "one per sensor";
  EXPECT_EQ(0, sensor_ends);
  ASSERT_FALSE(w.is_awake(box));
  EXPECT_EQ(std::vector<BodyId>{box}, w.sensor_contents(sensor));
  EXPECT_EQ(std::vector<BodyId>{box}, w.sensor_contents(other));
  w.remove_body(box);
  w.step();
  EXPECT_EQ(2u, w.sensor_events().size());
  for (const SensorEvent& e : w.sensor_events()) EXPECT_EQ(SensorEvent::Kind::end, e.kind);
  ASSERT_EQ(1u, w.contact_events().size());
  EXPECT_EQ(Kind::end, w.contact_events()[0].kind);
  EXPECT_EQ(ground, w.contact_events()[0].a);
  EXPECT_EQ(box, w.contact_events()[0].b);
  EXPECT_TRUE(w.sensor_contents(sensor).empty());
  EXPECT_THROW(w.sensor_contents(ground), WorldError);
}

// A world restored from a snapshot mid-fall and mid-rest reports what the original does.
TEST(ContactEvents, ARestoredSnapshotCarriesOnWithTheSameEvents) {
  World w;
  add_ground(w);
  const float half[3] = {1.5f, 1.5f, 0.5f}, at[3] = {0, 0, 0.5f};
  add_static_box(w, half, at, true);
  for (int i = 0; i < 6; ++i) drop(w, i % 2 ? Shape::box : Shape::sphere, 0.2f, 1.0f + i, 0.05f + 0.4f * i, 0.3f * i);
  for (int s = 0; s < 40; ++s) w.step();
  const std::vector<unsigned char> bytes = w.snapshot();
  std::unique_ptr<World> r = World::restore(bytes.data(), bytes.size());
  int events = 0;
  for (int s = 0; s < 120; ++s) {
    w.step();
    r->step();
    ASSERT_EQ(w.contact_events().size(), r->contact_events().size()) << "step " << s;
    for (size_t i = 0; i < w.contact_events().size(); ++i) {
      const ContactEvent &x = w.contact_events()[i], &y = r->contact_events()[i];
      EXPECT_TRUE(x.kind == y.kind && x.a == y.a && x.b == y.b && x.impulse == y.impulse) << "step " << s;
    }
    ASSERT_EQ(w.sensor_events().size(), r->sensor_events().size()) << "step " << s;
    events += int(w.contact_events().size() + w.sensor_events().size());
  }
  EXPECT_GT(events, 0) << "the scene should still have touches beginning after the snapshot";
}

}  // namespace
