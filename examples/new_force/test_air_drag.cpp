// air_drag's global set from a scene file reaches the kernel: falling_ball.json sets
// settings.air_drag.air_density, and its ball falls at the terminal speed of that density,
// sqrt(m g / (air_density drag)) -- at the file's density and at another set the same way.
// (A step at constant velocity has F = 0, so every integrator holds the terminal speed exactly.)
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>

#include "runtime/scene/scene.h"

namespace {

using namespace cellphys;

const std::string kScene = std::string(CELLPHYS_EXAMPLE_DIR) + "/falling_ball.json";
constexpr float kFileDensity = 0.736f;  // kg/m^3, air at 5,000 m: what falling_ball.json sets
constexpr float kHighDensity = 0.4135f;  // air at 10,000 m (neither the file's nor the default)

float drag_of(const scene::ForceSpec& f) {
  for (const auto& [name, value] : f.params)
    if (name == "drag") return value.at(0);
  ADD_FAILURE() << "no drag in the scene's air_drag";
  return 0;
}

// The ball's speed after 80 s of falling: more than ten time constants v_t / g for both densities.
void expect_terminal_speed(const scene::SceneDesc& d, double density) {
  ASSERT_EQ(d.bodies.size(), 1u);
  ASSERT_EQ(d.forces.size(), 1u);
  const double m = d.bodies[0].mass, g = -d.settings.globals.gravity[2], c = drag_of(d.forces[0]);
  const double want = std::sqrt(m * g / (density * c));
  scene::BuiltScene b = scene::build_world(d);
  const int steps = static_cast<int>(std::lround(80.0 / d.settings.dt));
  for (int i = 0; i < steps; ++i) b.world->step();
  const ppe::BodyState s = b.world->state(b.bodies[0]);
  EXPECT_NEAR(-s.velocity[2], want, 1e-4 * want) << "air_density " << density;
  EXPECT_EQ(s.velocity[0], 0.0f);
  EXPECT_EQ(s.velocity[1], 0.0f);
}

TEST(AirDrag, TheSceneFilesDensityGivesItsTerminalSpeed) {
  const scene::SceneDesc d = scene::load_scene(kScene);
  EXPECT_EQ(d.settings.globals.air_density, kFileDensity);
  expect_terminal_speed(d, kFileDensity);
}

TEST(AirDrag, AnotherDensityFromTheSettingsGivesItsTerminalSpeed) {
  std::ifstream in(kScene);
  std::stringstream text;
  text << in.rdbuf();
  nlohmann::json j = nlohmann::json::parse(text.str());
  j["settings"]["air_drag"]["air_density"] = kHighDensity;
  const scene::SceneDesc d = scene::parse_scene(j.dump(), "falling_ball_10km.json");
  EXPECT_EQ(d.settings.globals.air_density, kHighDensity);
  expect_terminal_speed(d, kHighDensity);
}

}  // namespace
