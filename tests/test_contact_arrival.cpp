// A body meets what it hits at the speed it had (docs/contacts.md, "What acts in a step"):
// falls, shots at a wall and a ball thrown at another are not braked, and nothing is pushed,
// before the bodies touch. Measured against free flight's closed form (the step's own: speed
// n g h after n steps, height z0 - g h^2 n (n + 1) / 2), for several shapes, sizes, masses and
// speeds; then how deep the landing sinks, against the soft contact's one-step closed form.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>

#include "runtime/ppe/world.h"

namespace {

using namespace cellphys::ppe;

constexpr double kG = 9.81;
constexpr double kTouch = 1e-3;  // a gap this small counts as touching (m)

BodyId add_ground(World& w) {
  const float up[3] = {0, 0, 1};
  BodyDesc d;
  d.shape = w.shapes().add_plane(up, 0.0f);
  d.is_static = true;
  return w.add_body(d);
}

enum class Shape { sphere, box, tilted_box };
const char* name_of(Shape s) { return s == Shape::sphere ? "sphere" : s == Shape::box ? "box" : "box on its edge"; }

struct FallCase {
  Shape shape;
  float size, mass, height;  // radius or half side (m), kg, lowest point above the ground (m)
};

// How far below its centre a body reaches: a box turned 30 degrees about x lands on an edge.
double extent(Shape s, float size) {
  if (s != Shape::tilted_box) return size;
  const double a = 30.0 * 3.14159265358979 / 180.0;
  return size * (std::sin(a) + std::cos(a));
}

// How far a body's lowest point is above z = 0: a sphere's centre less its radius, a box's
// lowest corner.
double lowest(const BodyState& b, Shape s, float size) {
  if (s == Shape::sphere) return b.position[2] - size;
  const double w = b.orientation[0], x = b.orientation[1], y = b.orientation[2], z = b.orientation[3];
  // the third row of the rotation matrix: a body axis's world height
  const double row[3] = {2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)};
  return b.position[2] - size * (std::fabs(row[0]) + std::fabs(row[1]) + std::fabs(row[2]));
}

// Whether a free-flight check holds to float rounding: the step's closed form, accumulated in
// float over n steps.
bool at_least(double v, double free) { return v >= free * (1 - 1e-4) - 1e-4; }

// The soft contact's one implicit step from a closing speed u with no depth: k = m w^2 and
// c = 2 zeta m w leave u / (1 + 2 zeta w h + (w h)^2) of it (docs/contacts.md).
double soft_step_left(const World& w, double u) {
  const double omega = 2 * 3.14159265358979 * w.settings().globals.contact_hertz, h = w.settings().dt;
  return u / (1 + 2 * w.settings().globals.contact_damping_ratio * omega * h + omega * omega * h * h);
}

class Falls : public ::testing::TestWithParam<FallCase> {};

// A dropped body falls freely, at the closed form's speed, until it touches the ground, and
// touches in the step the closed form says (or the one before: a gap the step leaves within
// contact.slop is closed in that step). It then sinks no deeper than the soft contact's one
// step from the speed it landed with, plus the hold depth.
TEST_P(Falls, FreeUntilTheGroundThenOneSoftStepDeep) {
  const FallCase c = GetParam();
  SCOPED_TRACE(std::string(name_of(c.shape)) + " size " + std::to_string(c.size) + " mass " + std::to_string(c.mass) +
               " height " + std::to_string(c.height));
  World w;
  add_ground(w);
  BodyDesc d;
  const float half[3] = {c.size, c.size, c.size};
  d.shape = c.shape == Shape::sphere ? w.shapes().add_sphere(c.size) : w.shapes().add_box(half);
  d.mass = c.mass;
  const double reach = extent(c.shape, c.size);
  if (c.shape == Shape::tilted_box) {
    const double a = 15.0 * 3.14159265358979 / 180.0;  // half of 30 degrees
    d.state.orientation[0] = float(std::cos(a));
    d.state.orientation[1] = float(std::sin(a));
  }
  d.state.position[2] = float(c.height + reach);
  const BodyId body = w.add_body(d);

  const double h = w.settings().dt;
  int touch = -1, free_touch = -1;
  double landing_speed = 0, deepest = 0;
  const int steps = int(std::lround((std::sqrt(2 * c.height / kG) + 2.0) / h));
  for (int n = 1; n <= steps; ++n) {
    w.step();
    const double gap = lowest(w.state(body), c.shape, c.size), speed = -w.state(body).velocity[2];
    if (free_touch < 0 && c.height - kG * h * h * n * (n + 1) / 2 <= kTouch) free_touch = n;
    if (touch < 0 && gap > kTouch) {
      ASSERT_TRUE(at_least(speed, kG * h * n)) << "braked at step " << n << ", " << gap << " m above the ground: "
                                               << speed << " m/s against free fall's " << kG * h * n;
      landing_speed = speed;
    } else if (touch < 0) {
      touch = n;
    }
    if (touch >= 0) deepest = std::max(deepest, -gap);
  }
  ASSERT_GE(touch, 0) << "it never reached the ground";
  EXPECT_GE(touch, free_touch - 1);
  EXPECT_LE(touch, free_touch);
  const double bound = h * soft_step_left(w, landing_speed + kG * h) + w.settings().globals.contact_hold_depth;
  EXPECT_LE(deepest, bound) << "landing at " << landing_speed << " m/s";
  ::testing::Test::RecordProperty("landing_speed", std::to_string(landing_speed));
  ::testing::Test::RecordProperty("deepest_m", std::to_string(deepest));
  ::testing::Test::RecordProperty("bound_m", std::to_string(bound));
}

INSTANTIATE_TEST_SUITE_P(ShapesSizesMassesHeights, Falls,
                         ::testing::Values(FallCase{Shape::sphere, 0.25f, 1.0f, 1.0f},
                                           FallCase{Shape::sphere, 0.5f, 80.0f, 2.0f},
                                           FallCase{Shape::sphere, 0.1f, 0.2f, 10.0f},
                                           FallCase{Shape::box, 0.5f, 10.0f, 0.5f},
                                           FallCase{Shape::box, 0.2f, 5000.0f, 3.0f},
                                           FallCase{Shape::tilted_box, 0.3f, 2.0f, 2.0f}));

struct ShotCase {
  float radius, mass, speed;
};

class Shots : public ::testing::TestWithParam<ShotCase> {};

// A ball shot at a wall (high above the ground, gravity on) keeps its speed until it touches
// the wall, in the step free flight says, and does not pass into it deeper than the soft
// contact's one step allows.
TEST_P(Shots, KeepTheirSpeedUntilTheWall) {
  const ShotCase c = GetParam();
  SCOPED_TRACE("radius " + std::to_string(c.radius) + " mass " + std::to_string(c.mass) + " speed " + std::to_string(c.speed));
  World w;
  BodyDesc wall;
  const float half[3] = {0.5f, 5.0f, 50.0f};
  wall.shape = w.shapes().add_box(half);
  wall.is_static = true;
  wall.state.position[0] = 0.5f;  // its face at x = 0
  w.add_body(wall);
  BodyDesc d;
  d.shape = w.shapes().add_sphere(c.radius);
  d.mass = c.mass;
  const double start_gap = 0.3 * c.speed + 0.137;  // not a whole number of steps away
  d.state.position[0] = float(-(c.radius + start_gap));
  d.state.position[2] = 20.0f;
  d.state.velocity[0] = c.speed;
  const BodyId ball = w.add_body(d);

  const double h = w.settings().dt;
  int touch = -1, free_touch = -1;
  double deepest = 0;
  for (int n = 1; n <= 60; ++n) {
    w.step();
    const double gap = -w.state(ball).position[0] - c.radius;
    if (free_touch < 0 && start_gap - c.speed * h * n <= kTouch) free_touch = n;
    if (touch < 0 && gap > kTouch) {
      ASSERT_TRUE(at_least(w.state(ball).velocity[0], c.speed))
          << "braked at step " << n << ", " << gap << " m from the wall: " << w.state(ball).velocity[0] << " m/s";
    } else if (touch < 0) {
      touch = n;
    }
    deepest = std::max(deepest, -gap);
  }
  ASSERT_GE(touch, 0);
  EXPECT_GE(touch, free_touch - 1);
  EXPECT_LE(touch, free_touch);
  EXPECT_LE(deepest, h * soft_step_left(w, c.speed) + w.settings().globals.contact_hold_depth);
  ::testing::Test::RecordProperty("deepest_m", std::to_string(deepest));
}

INSTANTIATE_TEST_SUITE_P(RadiiMassesSpeeds, Shots,
                         ::testing::Values(ShotCase{0.05f, 0.1f, 50.0f}, ShotCase{0.3f, 10.0f, 20.0f},
                                           ShotCase{1.0f, 1000.0f, 5.0f}, ShotCase{0.1f, 2.0f, 30.0f}));

// A ball thrown at a resting one (both in the air, so gravity moves them alike): the target does
// not move until the thrown ball touches it, at 1:1, 1:100 and 100:1.
TEST(Throws, TheTargetDoesNotMoveBeforeItIsTouched) {
  for (const float target_mass : {1.0f, 100.0f, 0.01f}) {
    SCOPED_TRACE("target mass " + std::to_string(target_mass));
    World w;
    BodyDesc thrown, target;
    thrown.shape = w.shapes().add_sphere(0.2f);
    thrown.mass = 1.0f;
    thrown.state.position[2] = 20.0f;
    thrown.state.velocity[0] = 10.0f;
    target.shape = w.shapes().add_sphere(0.3f);
    target.mass = target_mass;
    target.state.position[0] = 0.2f + 0.3f + 1.73f;
    target.state.position[2] = 20.0f;
    const BodyId a = w.add_body(thrown), b = w.add_body(target);
    bool touched = false;
    for (int n = 1; n <= 30 && !touched; ++n) {
      w.step();
      const double gap = w.state(b).position[0] - w.state(a).position[0] - 0.5;
      touched = gap <= kTouch;
      if (!touched) {
        EXPECT_EQ(0.0f, w.state(b).velocity[0]) << "pushed at step " << n << " from " << gap << " m away";
        EXPECT_TRUE(at_least(w.state(a).velocity[0], 10.0)) << "braked at step " << n << " " << gap << " m away";
      }
    }
    EXPECT_TRUE(touched);
  }
}

}  // namespace
