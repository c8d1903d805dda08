// The wheel joint (codegen/descriptors/forces/wheel.yaml) at 60 Hz with the default settings,
// against closed forms: a car's static sag on its springs, a wheel's bounce period on its
// suspension, a motor's spin-up under its torque limit, a free wheel's spin kept, the travel
// limit's stop, and a car driven by its motors rolling at the wheels' spin times their radius.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "runtime/ppe/world.h"
#include "tests/support/record.h"

namespace {

using namespace cellphys;
using cellphys::test_support::record;
using ppe::BodyDesc;
using ppe::BodyId;
using ppe::BodyState;
using ppe::World;
using ppe::WorldSettings;
using Vec3 = Eigen::Vector3d;
using Quat = Eigen::Quaterniond;

constexpr double kPi = 3.14159265358979323846;
constexpr double kG = 9.81;
constexpr int kHz = 60;

WorldSettings wheel_settings(bool gravity) {
  WorldSettings s;
  s.dt = 1.0f / kHz;
  s.sleeping = false;
  if (!gravity) s.globals.gravity[2] = 0.0f;
  return s;
}

Vec3 position(const BodyState& s) { return Vec3(s.position[0], s.position[1], s.position[2]); }
Vec3 velocity(const BodyState& s) { return Vec3(s.velocity[0], s.velocity[1], s.velocity[2]); }
Vec3 spin(const BodyState& s) { return Vec3(s.angular_velocity[0], s.angular_velocity[1], s.angular_velocity[2]); }
Quat orientation(const BodyState& s) {
  return Quat(s.orientation[0], s.orientation[1], s.orientation[2], s.orientation[3]).normalized();
}

BodyId add_body(World& w, uint32_t shape, double mass, const Vec3& at, double friction = 0.9) {
  BodyDesc d;
  d.shape = shape;
  d.mass = float(mass);
  d.friction = float(friction);
  for (int i = 0; i < 3; ++i) d.state.position[i] = float(at[i]);
  return w.add_body(d);
}

BodyId add_ground(World& w) {
  const float up[3] = {0, 0, 1};
  BodyDesc d;
  d.shape = w.shapes().add_plane(up, 0.0f);
  d.is_static = true;
  d.friction = 0.9f;
  return w.add_body(d);
}

// A wheel on `chassis` at `mount` (chassis frame), hanging along -z, its axle along y.
struct WheelJoint {
  Vec3 mount = Vec3::Zero();
  double stiffness = 0, damping = 0, rest = 0, lower = 0, upper = 0, motor_speed = 0, motor_torque = 0;
  ppe::ForceParams params() const {
    return {{"point_a", {float(mount.x()), float(mount.y()), float(mount.z())}},
            {"point_b", {0, 0, 0}},
            {"suspension_a", {0, 0, -1}},
            {"axis_a", {0, 1, 0}},
            {"axis_b", {0, 1, 0}},
            {"lower", {float(lower)}},
            {"upper", {float(upper)}},
            {"spring_stiffness", {float(stiffness)}},
            {"spring_damping", {float(damping)}},
            {"spring_travel", {float(rest)}},
            {"motor_speed", {float(motor_speed)}},
            {"motor_torque", {float(motor_torque)}}};
  }
};

// A box chassis on four sphere wheels standing on the ground, each spring at its rest travel.
struct Car {
  BodyId chassis = 0;
  std::vector<BodyId> wheels;
  double mass = 0, wheel_mass = 0, radius = 0;
  Vec3 mounts[4];
};

Car add_car(World& w, double mass, double wheel_mass, double radius, WheelJoint j, double drop = 0) {
  Car car;
  car.mass = mass, car.wheel_mass = wheel_mass, car.radius = radius;
  const float half[3] = {1.0f, 0.6f, 0.2f};
  const double ride = radius + j.rest + 0.3 + drop;  // chassis centre above the ground: mounts 0.3 below it
  car.chassis = add_body(w, w.shapes().add_box(half), mass, Vec3(0, 0, ride));
  const uint32_t ball = w.shapes().add_sphere(float(radius));
  int k = 0;
  for (double x : {-0.8, 0.8})
    for (double y : {-0.9, 0.9}) {
      car.mounts[k] = Vec3(x, y, -0.3);
      const BodyId wheel = add_body(w, ball, wheel_mass, Vec3(x, y, ride - 0.3 - j.rest));
      j.mount = car.mounts[k++];
      w.add_force("wheel", car.chassis, wheel, j.params());
      car.wheels.push_back(wheel);
    }
  return car;
}

// How far below its mount a wheel's centre is, along the chassis' -z.
double travel(const World& w, const Car& car, int k) {
  const BodyState c = w.state(car.chassis);
  const Vec3 mount = position(c) + orientation(c) * car.mounts[k];
  return -(orientation(c) * Vec3::UnitZ()).dot(position(w.state(car.wheels[k])) - mount);
}

// A car of 400-1600 kg on four springs settles where each spring carries a quarter of the
// chassis' weight: its travel is the rest travel less M g / 4k.
TEST(Wheel, CarSagsOnItsSpringsAsItsWeightSays) {
  for (double mass : {400.0, 1600.0})
    for (double stiffness : {2e4, 6e4}) {
      SCOPED_TRACE(std::to_string(mass) + " kg on " + std::to_string(stiffness) + " N/m");
      World w(wheel_settings(true));
      add_ground(w);
      WheelJoint j;
      j.stiffness = stiffness, j.rest = 0.3, j.damping = 2 * std::sqrt(stiffness * mass / 4);  // critically damped
      const Car car = add_car(w, mass, 15, 0.35, j);
      for (int i = 0; i < 4 * kHz; ++i) w.step();
      const double want = j.rest - mass * kG / (4 * stiffness);
      for (int k = 0; k < 4; ++k) EXPECT_NEAR(travel(w, car, k), want, 0.01 * (j.rest - want) + 1e-3) << "wheel " << k;
      EXPECT_LT(velocity(w.state(car.chassis)).norm(), 1e-3);
      record("wheel_sag_" + std::to_string(int(mass)) + "kg_" + std::to_string(int(stiffness)) + "npm_err_m",
             travel(w, car, 0) - want);
    }
}

// The same cars dropped 1 m land on their wheels and settle to the same sag, no island failing.
TEST(Wheel, DroppedCarLandsAndSettlesOnItsSprings) {
  for (double mass : {400.0, 1600.0}) {
    SCOPED_TRACE(std::to_string(mass) + " kg");
    World w(wheel_settings(true));
    add_ground(w);
    WheelJoint j;
    j.stiffness = 4e4, j.rest = 0.3, j.damping = 2 * std::sqrt(4e4 * mass / 4);
    const Car car = add_car(w, mass, 15, 0.35, j, 1.0);
    uint32_t failed = 0;
    for (int i = 0; i < 5 * kHz; ++i) failed += w.step().failed_islands;
    EXPECT_EQ(0u, failed);
    const double want = j.rest - mass * kG / (4 * j.stiffness);
    for (int k = 0; k < 4; ++k) EXPECT_NEAR(travel(w, car, k), want, 0.01 * (j.rest - want) + 1e-3) << "wheel " << k;
    EXPECT_LT(velocity(w.state(car.chassis)).norm(), 1e-3);
  }
}

// Without gravity, a 10 kg wheel on a 10^5 kg chassis, let go 5 cm off its rest travel, bounces
// on its undamped spring at 2 pi / w, w = sqrt(k / mu), mu the pair's reduced mass, as the
// linearly implicit step turns it: backward Euler's 2 pi h / atan(w h) (0.9-13% longer at
// w h = 0.17-0.67, the price of the step's unconditional stability: docs/integrators.md).
TEST(Wheel, BouncesAtItsSuspensionsPeriod) {
  for (double stiffness : {1e3, 4e3, 1.6e4}) {
    SCOPED_TRACE(std::to_string(stiffness) + " N/m");
    World w(wheel_settings(false));
    const float half[3] = {1.0f, 0.6f, 0.2f};
    const double big = 1e5, m = 10;
    const BodyId chassis = add_body(w, w.shapes().add_box(half), big, Vec3(0, 0, 5));
    const BodyId wheel = add_body(w, w.shapes().add_sphere(0.3f), m, Vec3(0, 0, 5 - 0.5 - 0.25));
    WheelJoint j;
    j.mount = Vec3(0, 0, -0.5), j.stiffness = stiffness, j.rest = 0.2;  // let go at 0.25: 5 cm out
    w.add_force("wheel", chassis, wheel, j.params());
    // the times the travel crosses its rest going down, over 3 s
    std::vector<double> crossings;
    double last = 0.05;
    for (int i = 1; i <= 3 * kHz; ++i) {
      w.step();
      const double off = (position(w.state(chassis)) - position(w.state(wheel))).z() - 0.5 - j.rest;
      if (last < 0 && off >= 0) crossings.push_back((i - 1 + -last / (off - last)) / kHz);
      last = off;
    }
    ASSERT_GE(crossings.size(), 3u);
    const double period = (crossings.back() - crossings.front()) / double(crossings.size() - 1);
    const double mu = m * big / (m + big), omega = std::sqrt(stiffness / mu), h = 1.0 / kHz;
    const double exact = 2 * kPi / omega, stepped = 2 * kPi * h / std::atan(omega * h);
    EXPECT_NEAR(period, stepped, 0.005 * stepped);
    record("wheel_bounce_" + std::to_string(int(stiffness)) + "npm_period_rel_err", period / exact - 1);
  }
}

// A wheel on a fixed axle (chassis 10^5 kg, no gravity) spun up by its motor: at its torque
// limit the spin grows at tau / I until the target speed, which it then holds.
TEST(Wheel, MotorSpinsUpAtItsTorqueLimitThenHoldsTheSpeed) {
  for (double torque : {2.0, 10.0}) {
    SCOPED_TRACE(std::to_string(torque) + " N m");
    World w(wheel_settings(false));
    const float half[3] = {1.0f, 0.6f, 0.2f};
    const double m = 8, r = 0.3, inertia = 0.4 * m * r * r;
    const BodyId chassis = add_body(w, w.shapes().add_box(half), 1e5, Vec3(0, 0, 5));
    const BodyId wheel = add_body(w, w.shapes().add_sphere(float(r)), m, Vec3(0, 0, 5 - 0.5 - 0.2));
    WheelJoint j;
    j.mount = Vec3(0, 0, -0.5), j.stiffness = 1e4, j.damping = 500, j.rest = 0.2;
    j.motor_speed = 30, j.motor_torque = torque;
    w.add_force("wheel", chassis, wheel, j.params());
    const double reach = j.motor_speed * inertia / torque;  // seconds to the target speed
    const int half_way = int(0.5 * reach * kHz);
    for (int i = 1; i <= half_way; ++i) w.step();
    const double at_half = spin(w.state(wheel)).y();
    EXPECT_NEAR(at_half, torque / inertia * half_way / kHz, 0.01 * at_half);
    for (int i = 0; i < int((reach + 1.0) * kHz); ++i) w.step();
    EXPECT_NEAR(spin(w.state(wheel)).y(), j.motor_speed, 1e-3 * j.motor_speed);
    EXPECT_LT(std::hypot(spin(w.state(wheel)).x(), spin(w.state(wheel)).z()), 1e-3) << "the axle turned";
  }
}

// A wheel spinning freely about its axle keeps its spin: the axle's damper acts across it only.
TEST(Wheel, FreeSpinKeepsItsSpeed) {
  World w(wheel_settings(false));
  const float half[3] = {1.0f, 0.6f, 0.2f};
  const BodyId chassis = add_body(w, w.shapes().add_box(half), 500, Vec3(0, 0, 5));
  BodyDesc d;
  d.shape = w.shapes().add_sphere(0.4f);
  d.mass = 20;
  d.state.position[2] = 5 - 0.5 - 0.2f;
  d.state.angular_velocity[1] = 20;
  const BodyId wheel = w.add_body(d);
  WheelJoint j;
  j.mount = Vec3(0, 0, -0.5), j.stiffness = 1e4, j.damping = 500, j.rest = 0.2;
  w.add_force("wheel", chassis, wheel, j.params());
  // Nothing acts along the axle and the wheel's centre stays on the chassis' line: the chassis
  // does not turn and the wheel keeps its 20 rad/s.
  for (int i = 0; i < 5 * kHz; ++i) w.step();
  const double relative = spin(w.state(wheel)).y() - spin(w.state(chassis)).y(), want = 20;
  EXPECT_NEAR(relative, want, 1e-3 * want);
  EXPECT_LT(spin(w.state(chassis)).norm(), 1e-3);
  record("wheel_free_spin_rel_err", relative / want - 1);
}

// A wheel hanging in gravity from a fixed chassis on a spring too weak for it stops on its
// travel limit without passing through it.
TEST(Wheel, TravelLimitStopsTheWheel) {
  World w(wheel_settings(true));
  const float half[3] = {1.0f, 0.6f, 0.2f};
  const BodyId chassis = add_body(w, w.shapes().add_box(half), 1e5, Vec3(0, 0, 5));
  w.add_force("fixed", chassis, ppe::kWorldBody,
              {{"point_a", {0, 0, 0}}, {"point_b", {0, 0, 5}}, {"axis_a", {1, 0, 0}}, {"axis_b", {1, 0, 0}},
               {"ref_a", {0, 1, 0}}, {"ref_b", {0, 1, 0}}});
  const BodyId wheel = add_body(w, w.shapes().add_sphere(0.3f), 10, Vec3(0, 0, 5 - 0.5 - 0.1));
  WheelJoint j;
  j.mount = Vec3(0, 0, -0.5), j.stiffness = 100, j.rest = 0.1, j.lower = -0.2, j.upper = 0.3;  // sag 1 m
  w.add_force("wheel", chassis, wheel, j.params());
  double deepest = 0;
  for (int i = 0; i < 3 * kHz; ++i) {
    w.step();
    deepest = std::max(deepest, (position(w.state(chassis)) - position(w.state(wheel))).z() - 0.5);
  }
  const double at_end = (position(w.state(chassis)) - position(w.state(wheel))).z() - 0.5;
  EXPECT_LT(deepest, j.upper + 0.01) << "passed through the limit";
  EXPECT_NEAR(at_end, j.upper, 5e-3);
  record("wheel_limit_overshoot_m", deepest - j.upper);
}

// A car driven by its four motors rolls without slipping: its speed is the wheels' spin times
// their radius.
TEST(Wheel, DrivenCarRollsAtSpinTimesRadius) {
  World w(wheel_settings(true));
  add_ground(w);
  WheelJoint j;
  j.stiffness = 4e4, j.rest = 0.3, j.damping = 2 * std::sqrt(4e4 * 800 / 4);
  j.motor_speed = 10, j.motor_torque = 400;  // 4 x 400 N m / 0.35 m: 0.58 g at most, under mu g
  const Car car = add_car(w, 800, 15, 0.35, j);
  for (int i = 0; i < 6 * kHz; ++i) w.step();
  const double speed = velocity(w.state(car.chassis)).x();
  for (BodyId wheel : car.wheels) EXPECT_NEAR(spin(w.state(wheel)).y(), j.motor_speed, 0.01 * j.motor_speed);
  EXPECT_NEAR(speed, j.motor_speed * car.radius, 0.02 * j.motor_speed * car.radius);
  EXPECT_LT(std::fabs(velocity(w.state(car.chassis)).y()), 0.01) << "drifted sideways";
  record("wheel_car_speed_mps", speed);
}

}  // namespace
