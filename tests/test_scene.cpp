// Scene files: every built-in scene reads, builds and round-trips (parse -> write -> parse is
// equal, and the rebuilt world steps bit-identically); pile65 is the fixture's pile_in_bin;
// every generated force type is reachable from a file by name; and each kind of bad input is
// refused with the file, the JSON path of the bad field and the reason.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "cellphys/gen/force_table.h"
#include "runtime/scene/scene.h"
#include "testing/ragdoll.h"
#include "testing/scenes.h"

namespace {

namespace fs = std::filesystem;
using namespace cellphys;
using scene::SceneDesc;
using scene::SceneError;

const std::string kScenes = CELLPHYS_SCENES_DIR;

std::vector<std::string> builtin_scene_files() {
  std::vector<std::string> out;
  for (const auto& e : fs::directory_iterator(kScenes))
    if (e.path().extension() == ".json") out.push_back(e.path().string());
  std::sort(out.begin(), out.end());
  return out;
}

// Steps a built scene and returns the state hash after each step.
std::vector<uint64_t> trajectory(const SceneDesc& d, int steps) {
  scene::BuiltScene b = scene::build_world(d);
  std::vector<uint64_t> h;
  for (int i = 0; i < steps; ++i) {
    b.world->step();
    h.push_back(b.world->state_hash());
  }
  return h;
}

// The SceneError a text raises (fails the test if none).
SceneError error_of(const std::string& text, bool build = false) {
  try {
    const SceneDesc d = scene::parse_scene(text, "bad.json");
    if (build) scene::build_world(d);
  } catch (const SceneError& e) {
    return e;
  }
  ADD_FAILURE() << "no error for: " << text;
  return SceneError("", "", "");
}

TEST(Scene, BuiltinScenesAreAllThere) {
  std::vector<std::string> names;
  for (const std::string& f : builtin_scene_files()) names.push_back(fs::path(f).stem().string());
  for (const char* want : {"world1000", "pile65", "stack10", "chain_ratio", "spin", "stiff_spring", "incline",
                           "pendulum", "newton_cradle", "ragdoll_pile", "door_and_bridge", "cars", "terrain"})
    EXPECT_NE(std::find(names.begin(), names.end(), want), names.end()) << want;
}

TEST(Scene, EveryBuiltinSceneLoadsBuildsAndRoundTrips) {
  for (const std::string& f : builtin_scene_files()) {
    SCOPED_TRACE(f);
    const SceneDesc d = scene::load_scene(f);
    EXPECT_FALSE(d.description.empty());
    EXPECT_EQ(d.description.find('\n'), std::string::npos) << "a description is one line";
    const scene::BuiltScene b = scene::build_world(d);
    EXPECT_EQ(b.world->num_bodies(), d.bodies.size());
    EXPECT_EQ(b.forces.size(), d.forces.size());
    EXPECT_TRUE(b.warnings.empty()) << b.warnings.front();
    const std::string text = scene::write_scene(d);
    const SceneDesc again = scene::parse_scene(text, "written.json");
    EXPECT_TRUE(again == d);
    EXPECT_EQ(scene::write_scene(again), text) << "writing is a fixed point";
  }
}

TEST(Scene, RoundTripGivesBitIdenticalTrajectories) {
  for (const char* name : {"pile65", "chain_ratio", "incline"}) {
    SCOPED_TRACE(name);
    const SceneDesc d = scene::load_scene(kScenes + "/" + name + ".json");
    const SceneDesc again = scene::parse_scene(scene::write_scene(d), "written.json");
    EXPECT_EQ(trajectory(d, 8), trajectory(again, 8));
  }
}

TEST(Scene, Pile65IsTheFixturesPileInBin) {
  const SceneDesc d = scene::load_scene(kScenes + "/pile65.json");
  const scene::BuiltScene b = scene::build_world(d);
  ppe::World w;
  cellphys::testing::pile_in_bin(w, 65, 0.25f, 1);
  ASSERT_EQ(w.num_bodies(), b.world->num_bodies());
  for (ppe::BodyId id : w.bodies()) {
    const ppe::BodyState s = w.state(id), t = b.world->state(id);
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(s.position[k], t.position[k], 1e-5f) << "body " << id;
    for (int k = 0; k < 4; ++k) EXPECT_NEAR(s.orientation[k], t.orientation[k], 1e-5f) << "body " << id;
    EXPECT_EQ(w.is_static(id), b.world->is_static(id));
    if (!w.is_static(id)) EXPECT_EQ(w.mass(id), b.world->mass(id));
  }
}

// The scene's first ragdoll is the fixture's (examples/scenes/make_scenes.py mirrors
// testing/ragdoll.cpp): the same bodies where the fixture puts them.
TEST(Scene, RagdollPileHoldsTheFixturesRagdoll) {
  const SceneDesc d = scene::load_scene(kScenes + "/ragdoll_pile.json");
  const scene::BuiltScene b = scene::build_world(d);
  ppe::World w;
  cellphys::testing::ground_plane(w, 0.6f);
  // lying: turned a quarter about x; at (-0.75, 0, 0.35); 1.5 m, 50 kg
  const float half = 0.70710678f, q[4] = {half, half, 0, 0}, pelvis[3] = {-0.75f, 0, 0.35f};
  const cellphys::testing::Ragdoll r = cellphys::testing::add_ragdoll(w, 1.5f, 50.0f, pelvis, q);
  for (ppe::BodyId id : r.parts) {
    const ppe::BodyState s = w.state(id), t = b.world->state(id);
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(s.position[k], t.position[k], 1e-5f) << cellphys::testing::Ragdoll::kPartNames[id - 1];
    for (int k = 0; k < 4; ++k) EXPECT_NEAR(s.orientation[k], t.orientation[k], 1e-5f) << "body " << id;
    EXPECT_FLOAT_EQ(w.mass(id), b.world->mass(id));
    EXPECT_FLOAT_EQ(w.scale(id), b.world->scale(id));
  }
  EXPECT_EQ(b.forces.size(), 8 * r.joints.size());
}

TEST(Scene, SettingsMapOntoWorldSettings) {
  const SceneDesc d = scene::parse_scene(R"({
    "settings": {"dt": 0.005, "gravity": [0, -1, -2], "integrator": "rosenbrock", "solver": "bicgstab",
                 "tolerance": 1e-5, "sleeping": false, "workers": 3, "max_halvings": 4,
                 "contact": {"stiffness": 2e5, "damping": 300, "slip_velocity": 0.02, "margin": 0.02},
                 "sleep": {"linear": 0.1, "angular": 0.2, "time": 1.5}}})",
                                         "s.json");
  const ppe::WorldSettings& s = d.settings;
  EXPECT_EQ(s.dt, 0.005f);
  EXPECT_EQ(s.globals.gravity[1], -1.0f);
  EXPECT_EQ(s.globals.gravity[2], -2.0f);
  EXPECT_EQ(s.integrator, spu::Integrator::rosenbrock);
  EXPECT_EQ(s.solver, spu::Solver::bicgstab);
  EXPECT_EQ(s.tolerance, 1e-5f);
  EXPECT_FALSE(s.sleeping);
  EXPECT_EQ(s.workers, 3);
  EXPECT_EQ(s.max_halvings, 4u);
  EXPECT_EQ(s.globals.contact_stiffness, 2e5f);
  EXPECT_EQ(s.globals.contact_damping, 300.0f);
  EXPECT_EQ(s.globals.slip_velocity, 0.02f);
  EXPECT_EQ(s.contact_margin, 0.02f);
  EXPECT_EQ(s.sleep_time, 1.5f);
  for (const char* name : {"implicit_split", "implicit_euler", "rosenbrock", "symplectic_euler", "explicit_euler", "rk4"}) {
    const SceneDesc e = scene::parse_scene(std::string(R"({"settings": {"integrator": ")") + name + "\"}}", "i.json");
    EXPECT_STREQ(spu::integrator_name(e.settings.integrator), name);
  }
  const SceneDesc defaults = scene::parse_scene("{}", "empty.json");
  EXPECT_EQ(defaults.settings.integrator, spu::Integrator::implicit_split);
  EXPECT_EQ(defaults.settings.solver, spu::Solver::cgs);
  EXPECT_TRUE(scene::operator==(defaults.settings, ppe::WorldSettings{}));
}

TEST(Scene, BodiesTakeStringOrIntegerIdsAndEveryField) {
  const SceneDesc d = scene::parse_scene(R"({
    "shapes": [{"name": "b", "type": "box", "half_extents": [0.1, 0.2, 0.3]},
               {"name": "floor", "type": "plane", "normal": [0, 0, 1]}],
    "bodies": [{"id": 7, "shape": "b", "scale": 2, "mass": 3, "inertia": [1, 2, 3, 0, 0, 0.1],
                "position": [1, 2, 3], "orientation": [0, 2, 0, 0], "velocity": [4, 5, 6],
                "angular_velocity": [0.1, 0.2, 0.3], "friction": 0.9, "damping": {"linear": 0.1, "angular": 0.2}},
               {"id": "floor", "shape": "floor"},
               {"id": "light", "shape": "b", "density": 500, "damping": 0.5},
               {"id": "trigger", "shape": "b", "static": true, "sensor": true}],
    "forces": [{"type": "spring", "a": 7, "b": "light", "stiffness": 10, "rest_length": 1}]})",
                                         "ids.json");
  ASSERT_EQ(d.bodies.size(), 4u);
  EXPECT_TRUE(d.bodies[3].sensor);
  EXPECT_FALSE(d.bodies[2].sensor);
  EXPECT_EQ(d.bodies[0].id, "7");
  EXPECT_TRUE(d.bodies[0].id_is_integer);
  EXPECT_EQ(d.bodies[0].inertia[5], 0.1f);
  EXPECT_EQ(d.bodies[0].angular_damping, 0.2f);
  EXPECT_EQ(d.bodies[2].linear_damping, 0.5f);
  EXPECT_EQ(d.forces[0].a, "7");
  const std::string text = scene::write_scene(d);
  EXPECT_NE(text.find("\"id\": 7"), std::string::npos) << text;
  EXPECT_TRUE(scene::parse_scene(text, "again.json") == d);
  const scene::BuiltScene b = scene::build_world(d);
  EXPECT_EQ(b.world->mass(b.bodies[0]), 3.0f);
  EXPECT_TRUE(b.world->is_static(b.bodies[1]));
  EXPECT_TRUE(b.world->is_sensor(b.bodies[3]));
  EXPECT_FALSE(b.world->is_sensor(b.bodies[0]));
  EXPECT_EQ(b.world->inertia_body(b.bodies[0])[1], 2.0f);
  ASSERT_EQ(b.warnings.size(), 1u) << "the orientation [0, 2, 0, 0] is normalised";
  EXPECT_NE(b.warnings[0].find("ids.json: bodies[0]: "), std::string::npos) << b.warnings[0];
}

// Every non-global force the generator knows (including ones added later by descriptor) can be
// added from a scene by its type name with its parameters by name, with no C++ change here.
TEST(Scene, EveryGeneratedForceTypeIsReachableByName) {
  int reached = 0;
  for (const gen::ForceInfo& f : gen::kForceTable) {
    if (f.kind == gen::ForceKind::global) continue;
    SCOPED_TRACE(f.name);
    std::ostringstream force;
    force << R"({"type": ")" << f.name << R"(", "a": "p")";
    if (f.kind == gen::ForceKind::binary) force << R"(, "b": "q")";
    for (uint32_t k = 0; k < f.num_params; ++k) {
      const gen::ParamInfo& p = f.params[k];
      force << ", \"" << p.name << "\": " << (p.type == gen::ParamType::vec3 ? "[0, 0, 0.1]" : "0.5");
    }
    force << "}";
    const std::string text = R"({"shapes": [{"name": "s", "type": "sphere", "radius": 0.1}],
      "bodies": [{"id": "p", "shape": "s", "mass": 1}, {"id": "q", "shape": "s", "mass": 1, "position": [1, 0, 0]}],
      "forces": [)" + force.str() + "]}";
    const SceneDesc d = scene::parse_scene(text, "forces.json");
    ASSERT_EQ(d.forces.size(), 1u);
    EXPECT_EQ(d.forces[0].params.size(), f.num_params);
    scene::BuiltScene b = scene::build_world(d);
    EXPECT_EQ(b.forces.size(), 1u);
    b.world->step();
    EXPECT_TRUE(scene::parse_scene(scene::write_scene(d), "again.json") == d);
    ++reached;
  }
  EXPECT_GE(reached, 5);
}

// Every force global sits in settings at its generated place (gravity at the top, a global
// <force>_<key> at <force>.<key>, another at <force>.<name>), is read, written and compared
// there, and is held to its declared bound, by the reader and by the World alike: a new force's
// global needs no C++ change.
TEST(Scene, EveryForceGlobalIsSetAtItsPlaceInSettings) {
  ASSERT_GT(gen::kNumGlobals, 0);
  for (int i = 0; i < gen::kNumGlobals; ++i) {
    const gen::GlobalInfo& g = gen::kGlobalTable[i];
    SCOPED_TRACE(g.param.name);
    const std::string setting = g.setting, name = g.param.name;
    const size_t dot = setting.find('.');
    if (dot == std::string::npos) {
      EXPECT_EQ(setting, name);
    }
    auto at_place = [&](const std::string& value) {
      const std::string leaf = "\"" + setting.substr(dot + 1) + "\": " + value;
      return R"({"settings": {)" + (dot == std::string::npos ? leaf : "\"" + setting.substr(0, dot) + "\": {" + leaf + "}") +
             "}}";
    };
    const float base = g.param.has_min ? g.param.min : 0.0f;
    const std::string value = g.param.lanes == 1 ? std::to_string(base + 1.5f)
                                                 : "[" + std::to_string(base + 1.5f) + ", 2.5, -3.5]";
    const SceneDesc d = scene::parse_scene(at_place(value), "globals.json");
    const float* lanes = reinterpret_cast<const float*>(reinterpret_cast<const unsigned char*>(&d.settings.globals) +
                                                        g.field_offset);
    EXPECT_EQ(lanes[0], base + 1.5f);
    EXPECT_FALSE(scene::operator==(d.settings, ppe::WorldSettings{}));
    EXPECT_TRUE(scene::parse_scene(scene::write_scene(d), "again.json") == d);
    EXPECT_NO_THROW(scene::build_world(d));
    if (!g.param.has_min) continue;
    const std::string below = std::to_string(g.param.min_exclusive ? g.param.min : g.param.min - 1.0f);
    try {
      scene::parse_scene(at_place(g.param.lanes == 1 ? below : "[" + below + ", 0, 0]"), "low.json");
      ADD_FAILURE() << "below its bound, accepted";
    } catch (const SceneError& e) {
      EXPECT_EQ(e.path(), "settings." + setting + (g.param.lanes == 1 ? "" : "[0]")) << e.what();
      EXPECT_NE(e.reason().find("must be"), std::string::npos) << e.what();
    }
    ppe::WorldSettings s = d.settings;
    float* bad = reinterpret_cast<float*>(reinterpret_cast<unsigned char*>(&s.globals) + g.field_offset);
    bad[0] = g.param.min_exclusive ? g.param.min : g.param.min - 1.0f;
    try {
      ppe::World w(s);
      ADD_FAILURE() << "below its bound, accepted by the World";
    } catch (const ppe::WorldError& e) {
      EXPECT_NE(std::string(e.what()).find("settings.globals." + name), std::string::npos) << e.what();
    }
  }
}

struct BadCase {
  const char* what;
  std::string text;
  std::string path;    // expected JSON path
  std::string reason;  // a substring of the reason
  bool build = false;  // refused by the World when building, not by the reader
};

const char kShapes[] = R"("shapes": [{"name": "s", "type": "sphere", "radius": 0.1}])";
std::string with_bodies(const std::string& bodies, const std::string& rest = "") {
  return std::string("{") + kShapes + R"(, "bodies": [)" + bodies + "]" + rest + "}";
}
const char kB0[] = R"({"id": "a", "shape": "s", "mass": 1})";
const char kB1[] = R"({"id": "b", "shape": "s", "mass": 1, "position": [1, 0, 0]})";

std::vector<BadCase> bad_cases() {
  const std::string two = std::string(kB0) + ", " + kB1;
  return {
      {"unknown top-level field", R"({"bodys": []})", "bodys", "unknown field 'bodys'"},
      {"unknown settings field", R"({"settings": {"dtt": 0.1}})", "settings.dtt", "unknown field"},
      {"unknown body field", with_bodies(std::string(kB0) + R"(, {"id": "b", "shape": "s", "mass": 1, "colour": 1})"),
       "bodies[1].colour", "unknown field 'colour'"},
      {"unknown shape field", R"({"shapes": [{"name": "s", "type": "sphere", "radius": 1, "half_extents": [1, 1, 1]}]})",
       "shapes[0].half_extents", "unknown field"},
      {"sensor not a boolean", with_bodies(std::string(kB0) + R"(, {"id": "b", "shape": "s", "mass": 1, "sensor": 1})"),
       "bodies[1].sensor", "expected"},
      {"wrong type (string for a number)", with_bodies(std::string(kB0) + R"(, {"id": "b", "shape": "s", "mass": "1"})"),
       "bodies[1].mass", "expected a number, got a string"},
      {"wrong type inside a vector",
       with_bodies(two + R"(, {"id": "c", "shape": "s", "mass": 1}, {"id": "d", "shape": "s", "mass": 1, "position": [0, "x", 0]})"),
       "bodies[3].position[1]", "expected a number"},
      {"wrong vector length", with_bodies(R"({"id": "a", "shape": "s", "mass": 1, "velocity": [1, 2]})"),
       "bodies[0].velocity", "expected 3 numbers, got 2"},
      {"wrong type for the bodies list", R"({"bodies": {}})", "bodies", "expected an array"},
      {"boolean expected", R"({"settings": {"sleeping": 1}})", "settings.sleeping", "expected true or false"},
      {"missing body (force a)", with_bodies(two, R"(, "forces": [{"type": "spring", "a": "zz", "b": "b"}])"),
       "forces[0].a", "no body with id 'zz'"},
      {"missing body (force b)", with_bodies(two, R"(, "forces": [{"type": "spring", "a": "a", "b": 12}])"),
       "forces[0].b", "no body with id '12'"},
      {"unknown shape", with_bodies(R"({"id": "a", "shape": "cube", "mass": 1})"), "bodies[0].shape",
       "unknown shape 'cube'"},
      {"unknown shape type", R"({"shapes": [{"name": "s", "type": "torus"}]})", "shapes[0].type",
       "unknown shape type 'torus'"},
      {"unknown force type", with_bodies(two, R"(, "forces": [{"type": "glue", "a": "a", "b": "b"}])"),
       "forces[0].type", "unknown force type 'glue'"},
      {"global force type", with_bodies(two, R"(, "forces": [{"type": "gravity", "a": "a"}])"), "forces[0].type",
       "global"},
      {"unknown force parameter",
       with_bodies(two, R"(, "forces": [{"type": "spring", "a": "a", "b": "b", "stifness": 3}])"),
       "forces[0].stifness", "unknown parameter 'stifness' for force 'spring'"},
      {"force parameter of the wrong shape",
       with_bodies(two, R"(, "forces": [{"type": "point_to_point", "a": "a", "b": "b", "point_a": 1}])"),
       "forces[0].point_a", "expected an array"},
      {"force parameter below its minimum",
       with_bodies(two, R"(, "forces": [{"type": "spring", "a": "a", "b": "b", "stiffness": -1}])"),
       "forces[0].stiffness", "must be >= 0"},
      {"non-finite number", with_bodies(R"({"id": "a", "shape": "s", "mass": 1, "position": [0, 1e999, 0]})"),
       "bodies[0].position[1]", "not finite"},
      {"number too large for a float", with_bodies(R"({"id": "a", "shape": "s", "mass": 1e39})"), "bodies[0].mass",
       "32-bit float"},
      {"bad shape (World's validation)", R"({"shapes": [{"name": "s", "type": "sphere", "radius": -1}]})",
       "shapes[0]", "radius", true},
      {"bad hull (World's validation)",
       R"({"shapes": [{"name": "h", "type": "hull", "points": [[0, 0, 0], [1, 0, 0], [0, 1, 0]]}]})", "shapes[0]",
       "hull", true},
      {"bad body (World's validation)", with_bodies(R"({"id": "a", "shape": "s", "mass": 1, "orientation": [0, 0, 0, 0]})"),
       "bodies[0]", "zero quaternion", true},
      {"force on a static body (World's validation)",
       with_bodies(R"({"id": "a", "shape": "s", "static": true}, {"id": "b", "shape": "s", "mass": 1})",
                   R"(, "forces": [{"type": "spring", "a": "a", "b": "b"}])"),
       "forces[0]", "static", true},
      {"dynamic body without mass", with_bodies(R"({"id": "a", "shape": "s"})"), "bodies[0]", "needs a mass or a density"},
      {"mass and density", with_bodies(R"({"id": "a", "shape": "s", "mass": 1, "density": 2})"), "bodies[0].density",
       "not both"},
      {"duplicate body id", with_bodies(R"({"id": "a", "shape": "s", "mass": 1}, {"id": "a", "shape": "s", "mass": 1})"),
       "bodies[1].id", "already exists"},
      {"integer and string ids collide", with_bodies(R"({"id": 1, "shape": "s", "mass": 1}, {"id": "1", "shape": "s", "mass": 1})"),
       "bodies[1].id", "already exists"},
      {"reserved id", with_bodies(R"({"id": "world", "shape": "s", "mass": 1})"), "bodies[0].id", "reserved"},
      {"duplicate key", with_bodies(R"({"id": "a", "shape": "s", "mass": 1, "mass": 2})"), "bodies[0].mass",
       "duplicate key 'mass'"},
      {"unknown integrator", R"({"settings": {"integrator": "verlet"}})", "settings.integrator", "unknown integrator"},
      {"unknown solver", R"({"settings": {"solver": "gmres"}})", "settings.solver", "unknown solver"},
      {"workers out of range", R"({"settings": {"workers": 0}})", "settings.workers", "between 1 and 256"},
      {"negative dt", R"({"settings": {"dt": -0.01}})", "settings.dt", "must be positive"},
      {"negative count: the setting's bounds, not its type's", R"({"settings": {"max_halvings": -1}})",
       "settings.max_halvings", "between 0 and 16"},
      {"negative local store: the setting's bounds", R"({"settings": {"local_store_bytes": -1}})",
       "settings.local_store_bytes", "between 16384 and 1073741824"},
      {"local store over 1 GiB", R"({"settings": {"local_store_bytes": 2147483648}})", "settings.local_store_bytes",
       "between 16384 and 1073741824"},
      {"truncated file", with_bodies(two).substr(0, with_bodies(two).size() - 20), "bodies[1]", "not valid JSON"},
      {"not JSON", "shapes: [sphere]\n", "", "not valid JSON"},
      {"empty file", "", "", "not valid JSON"},
      {"not an object", "[1, 2, 3]", "", "expected an object"},
  };
}

TEST(Scene, BadInputIsRefusedWithFilePathAndReason) {
  for (const BadCase& c : bad_cases()) {
    SCOPED_TRACE(c.what);
    if (c.build) {  // the reader accepts it; the World refuses it
      EXPECT_NO_THROW(scene::parse_scene(c.text, "bad.json"));
    }
    const SceneError e = error_of(c.text, c.build);
    EXPECT_EQ(e.file(), "bad.json");
    EXPECT_EQ(e.path(), c.path) << e.what();
    EXPECT_NE(e.reason().find(c.reason), std::string::npos) << e.what();
    const std::string what = e.what();
    EXPECT_EQ(what.rfind("bad.json: ", 0), 0u) << what;
    if (!c.path.empty()) EXPECT_NE(what.find(": " + c.path + ": "), std::string::npos) << what;
  }
}

TEST(Scene, MissingFileIsASceneError) {
  try {
    scene::load_scene("/nonexistent/scene.json");
    FAIL() << "no error";
  } catch (const SceneError& e) {
    EXPECT_EQ(e.file(), "/nonexistent/scene.json");
    EXPECT_NE(e.reason().find("cannot open"), std::string::npos);
  }
}

TEST(Scene, BuildReportsBadReferencesInHandMadeDescriptions) {
  SceneDesc d;
  d.source = "made.cpp";
  scene::BodySpec b;
  b.id = "x";
  b.shape = "nothing";
  b.mass = 1;
  d.bodies.push_back(b);
  try {
    scene::build_world(d);
    FAIL() << "no error";
  } catch (const SceneError& e) {
    EXPECT_EQ(e.path(), "bodies[0].shape");
  }
}

}  // namespace

namespace {

// The complete example in docs/scene-format.md reads, builds and steps.
TEST(Scene, TheDocumentedExampleWorks) {
  std::ifstream in(kScenes + "/../../docs/scene-format.md");
  ASSERT_TRUE(in) << "docs/scene-format.md";
  std::stringstream ss;
  ss << in.rdbuf();
  const std::string doc = ss.str();
  const size_t start = doc.find("```json\n");
  ASSERT_NE(start, std::string::npos);
  const size_t end = doc.find("```", start + 8);
  const SceneDesc d = scene::parse_scene(doc.substr(start + 8, end - start - 8), "scene-format.md");
  EXPECT_EQ(d.bodies.size(), 5u);
  EXPECT_EQ(d.forces.size(), 3u);
  scene::BuiltScene b = scene::build_world(d);
  for (int i = 0; i < 10; ++i) b.world->step();
  EXPECT_TRUE(std::isfinite(b.world->kinetic_energy()));
}

}  // namespace
