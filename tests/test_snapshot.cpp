// World snapshots: save -> restore -> continue equals an uninterrupted run bit for bit, and a
// damaged snapshot is refused with the reason: damage on the way by the checksum, a record
// that was written wrong (and sealed again) by the field, the record's index and why.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <functional>
#include <limits>

#include "runtime/ppe/world.h"
#include "runtime/scene/scene.h"
#include "runtime/spu/island_image.h"
#include "testing/ragdoll.h"
#include "testing/scenes.h"

namespace {

using cellphys::ppe::World;
using cellphys::ppe::WorldError;

std::string scene_file(const char* name) { return std::string(CELLPHYS_SCENES_DIR) + "/" + name + ".json"; }

std::vector<unsigned char> without_pair_drift(std::vector<unsigned char> b);  // below

// Steps `before`, snapshots, then steps the original and the restored world side by side.
void check_resume(World& w, int before, int after) {
  for (int s = 0; s < before; ++s) w.step();
  const std::vector<unsigned char> bytes = w.snapshot();
  std::unique_ptr<World> r = World::restore(bytes.data(), bytes.size());
  EXPECT_EQ(r->state_hash(), w.state_hash());
  EXPECT_EQ(r->snapshot(), bytes) << "a restored world saves the same bytes";
  EXPECT_EQ(r->num_bodies(), w.num_bodies());
  for (int s = 0; s < after; ++s) {
    const auto& a = w.step();
    const auto& b = r->step();
    ASSERT_EQ(a.step, b.step);
    ASSERT_EQ(w.state_hash(), r->state_hash()) << "diverged at step " << a.step;
    ASSERT_EQ(a.sleeping_bodies, b.sleeping_bodies);
    ASSERT_EQ(a.contacts, b.contacts);
  }
}

TEST(Snapshot, Pile65ResumesBitForBit) {
  auto built = cellphys::scene::build_world(cellphys::scene::load_scene(scene_file("pile65")));
  check_resume(*built.world, 40, 40);
}

// Hulls of clouds that are not point-symmetric (world1000's are) sit on their centre of mass
// only to rounding: the restore takes their vertices as saved instead of re-centring them again.
TEST(Snapshot, HullsOfArbitraryCloudsResumeBitForBit) {
  for (uint32_t seed : {1u, 2u, 3u}) {
    SCOPED_TRACE(seed);
    World w;
    cellphys::testing::sparse_world(w, 100, 20.0f, seed);
    check_resume(w, 5, 10);
  }
}

TEST(Snapshot, World1000WithSleepersAndHullsResumesBitForBit) {
  auto built = cellphys::scene::build_world(cellphys::scene::load_scene(scene_file("world1000")));
  World& w = *built.world;
  for (int s = 0; s < 50; ++s) w.step();
  ASSERT_GT(w.last_stats().sleeping_bodies, 0u) << "the snapshot should hold sleeping groups";
  check_resume(w, 0, 25);
}

// What the World keeps passes the restore's checks of every record: each built-in scene
// (world1000 above) after a second of motion, with its joints, springs and sleepers.
TEST(Snapshot, EveryBuiltInSceneResumesAfterASecond) {
  for (const char* name : {"stack10", "chain_ratio", "incline", "newton_cradle", "pendulum", "spin", "stiff_spring",
                           "ragdoll_pile", "door_and_bridge", "cars", "terrain"}) {
    SCOPED_TRACE(name);
    auto built = cellphys::scene::build_world(cellphys::scene::load_scene(scene_file(name)));
    check_resume(*built.world, 60, 2);
  }
}

TEST(Snapshot, ForcesRemovedBodiesAndSettingsSurvive) {
  World w;
  cellphys::testing::ground_plane(w);
  const auto boxes = cellphys::testing::stack(w, 4, 0.25f, 0.01f);
  w.add_force("spring", boxes[2], boxes[3], {{"stiffness", {50.0f}}, {"rest_length", {0.5f}}});
  w.remove_body(boxes[1]);
  auto s = w.settings();
  s.integrator = cellphys::spu::Integrator::rosenbrock;
  s.globals.contact_slop = 0.004f;
  w.set_settings(s);
  check_resume(w, 10, 20);
  const auto bytes = w.snapshot();
  auto r = World::restore(bytes.data(), bytes.size());
  EXPECT_EQ(r->settings().integrator, cellphys::spu::Integrator::rosenbrock);
  EXPECT_EQ(r->settings().globals.contact_slop, 0.004f);
  EXPECT_EQ(r->last_stats().step, w.last_stats().step);
  EXPECT_THROW(r->state(boxes[1]), WorldError) << "a removed body stays removed";
  EXPECT_EQ(r->bodies(), w.bodies());
}

TEST(Snapshot, DamageIsRefusedWithTheReason) {
  World w;
  cellphys::testing::ground_plane(w);
  cellphys::testing::stack(w, 3, 0.25f);
  w.step();
  const std::vector<unsigned char> good = w.snapshot();
  auto refused = [&](std::vector<unsigned char> b, const char* why) {
    try {
      World::restore(b.data(), b.size());
      ADD_FAILURE() << "accepted; expected: " << why;
    } catch (const WorldError& e) {
      EXPECT_NE(std::string(e.what()).find(why), std::string::npos) << e.what();
    }
  };
  std::vector<unsigned char> b = good;
  b[good.size() / 2] ^= 0x10;
  refused(b, "checksum mismatch");
  refused(std::vector<unsigned char>(good.begin(), good.end() - 4), "payload bytes");
  refused(std::vector<unsigned char>(good.begin(), good.begin() + 10), "shorter than its header");
  b = good;
  b[0] = 'X';
  refused(b, "bad magic");
  b = good;
  b[8] = 1;  // the first format, before settings were stored by name
  refused(b, "format version 1");
  b[8] = 99;
  refused(b, "format version 99");
}

// Sensors and the events' memory survive: the restored world reports the same events and holds
// the same bodies in its sensor. A version-4 snapshot (no event memory, no sensors) still
// restores: the same world, its touches reported as begun by its first step.
TEST(Snapshot, SensorsAndTheEventMemorySurviveAndVersion4StillReads) {
  World w;
  cellphys::testing::ground_plane(w);
  const auto boxes = cellphys::testing::stack(w, 3, 0.25f);
  cellphys::ppe::BodyDesc trigger;
  const float half[3] = {1, 1, 1};
  trigger.shape = w.shapes().add_box(half);
  trigger.is_static = true;
  trigger.sensor = true;
  const cellphys::ppe::BodyId sensor = w.add_body(trigger);
  for (int s = 0; s < 5; ++s) w.step();
  ASSERT_FALSE(w.sensor_contents(sensor).empty());
  check_resume(w, 0, 10);
  std::vector<unsigned char> b = w.snapshot();
  auto r = World::restore(b.data(), b.size());
  EXPECT_TRUE(r->is_sensor(sensor));
  EXPECT_EQ(w.sensor_contents(sensor), r->sensor_contents(sensor));
  w.step();
  r->step();
  EXPECT_TRUE(r->contact_events().empty() && w.contact_events().empty()) << "nothing begins or ends at rest";

  World v4;
  cellphys::testing::ground_plane(v4);
  cellphys::testing::stack(v4, 3, 0.25f);
  for (int s = 0; s < 5; ++s) v4.step();
  b = v4.snapshot();
  // Version 4 is version 5 without the event memory at the end: the touching pairs (the stack's
  // three) and no sensor overlaps, each a u32 count and u64 keys.
  const size_t tail = 4 + 3 * 8 + 4;
  std::vector<unsigned char> old = without_pair_drift(std::vector<unsigned char>(b.begin(), b.end() - tail));
  old[8] = 4;
  const uint64_t payload = old.size() - 32;
  std::memcpy(&old[16], &payload, 8);
  const uint32_t sum = cellphys::spu::checksum(old.data() + 32, payload);
  std::memcpy(&old[24], &sum, 4);
  auto o = World::restore(old.data(), old.size());
  EXPECT_EQ(v4.state_hash(), o->state_hash());
  v4.step();
  o->step();
  EXPECT_EQ(v4.state_hash(), o->state_hash());
  EXPECT_TRUE(v4.contact_events().empty());
  EXPECT_EQ(3u, o->contact_events().size()) << "without a memory, the first step begins every touch";
  (void)boxes;
}

// Settings are stored by name: one this build lacks (from a build with other forces, say) is
// refused by its name, as is one this build has that the snapshot lacks.
TEST(Snapshot, SettingsAreMatchedByName) {
  World w;
  cellphys::testing::ground_plane(w);
  w.step();
  const std::vector<unsigned char> good = w.snapshot();
  const std::string name = cellphys::gen::kGlobalTable[0].setting;
  const auto at = std::search(good.begin() + 32, good.end(), name.begin(), name.end());
  ASSERT_NE(at, good.end());
  std::vector<unsigned char> b = good;
  b[at - good.begin() + name.size() - 1] = '#';
  const uint32_t sum = cellphys::spu::checksum(b.data() + 32, b.size() - 32);  // sealed again: only the name differs
  std::memcpy(b.data() + 24, &sum, 4);
  try {
    World::restore(b.data(), b.size());
    ADD_FAILURE() << "accepted a setting this build lacks";
  } catch (const WorldError& e) {
    const std::string renamed = name.substr(0, name.size() - 1) + "#";
    EXPECT_NE(std::string(e.what()).find("setting '" + renamed + "', which this build lacks"), std::string::npos)
        << e.what();
  }
}

// ---- records written wrong: each field refused by name, the world in hand unchanged ----

// Where the records of a snapshot start (the layout in runtime/ppe/snapshot.cpp), for a world
// of planes, spheres, capsules and boxes.
struct Layout {
  size_t bodies = 0;                  // the body count; body i at body(i)
  std::vector<size_t> forces;         // each force record
  std::vector<size_t> instances;      // each force's instance bytes
  size_t groups = 0;                  // the sleeping group count
  std::vector<size_t> group_contacts; // each group's contact count
  size_t free = 0;                    // the free slot count
  size_t pairs = 0;                   // the contact memory's pair count; the first pair after it
  static constexpr size_t kBodyBytes = 136, kContactBytes = 72;
  size_t body(uint32_t i) const { return bodies + 4 + i * kBodyBytes; }
};

uint32_t u32_at(const std::vector<unsigned char>& b, size_t at) {
  uint32_t v;
  std::memcpy(&v, b.data() + at, 4);
  return v;
}

Layout layout_of(const std::vector<unsigned char>& b) {
  Layout l;
  size_t at = 32;
  const uint32_t settings = u32_at(b, at);
  at += 4;
  for (uint32_t k = 0; k < 2 * settings; ++k) at += 4 + u32_at(b, at);  // name, value
  at += 8;  // step counter
  const uint32_t shapes = u32_at(b, at);
  at += 4;
  for (uint32_t k = 0; k < shapes; ++k) {
    const auto type = static_cast<cellphys::spu::ShapeType>(u32_at(b, at));
    at += 4;
    switch (type) {
      case cellphys::spu::ShapeType::sphere: at += 4; break;
      case cellphys::spu::ShapeType::capsule: at += 8; break;
      case cellphys::spu::ShapeType::box: at += 12; break;
      case cellphys::spu::ShapeType::plane: at += 16; break;
      default: ADD_FAILURE() << "layout_of reads planes, spheres, capsules and boxes only"; return l;
    }
  }
  l.bodies = at;
  at += 4 + u32_at(b, at) * Layout::kBodyBytes;
  const uint32_t forces = u32_at(b, at);
  at += 4;
  for (uint32_t k = 0; k < forces; ++k) {
    l.forces.push_back(at);
    at += 1;
    at += 4 + u32_at(b, at) + 8;  // name, a, b
    l.instances.push_back(at + 4);
    at += 4 + u32_at(b, at);
  }
  l.groups = at;
  const uint32_t groups = u32_at(b, at);
  at += 4;
  for (uint32_t g = 0; g < groups; ++g) {
    at += 4 + 4 * u32_at(b, at);
    l.group_contacts.push_back(at);
    at += 4 + u32_at(b, at) * Layout::kContactBytes;
  }
  l.free = at;
  at += 4 + 4 * u32_at(b, at);
  l.pairs = at;
  return l;
}

template <class T>
void put_at(std::vector<unsigned char>& b, size_t at, T v) {
  std::memcpy(b.data() + at, &v, sizeof v);
}

// Seals a snapshot again after an edit: its payload size and checksum, so only the edit is wrong.
void seal(std::vector<unsigned char>& b) {
  put_at<uint64_t>(b, 16, b.size() - 32);
  put_at<uint32_t>(b, 24, cellphys::spu::checksum(b.data() + 32, b.size() - 32));
}

// Ground (body 0), two boxes stacked, asleep (1, 2), a removed sphere (3) and two spheres
// joined by a spring (4, 5), thrown: a sleeping group with its contacts, contact memory, a
// live and a removed force.
std::unique_ptr<World> edited_world() {
  auto w = std::make_unique<World>();
  cellphys::testing::ground_plane(*w);
  cellphys::testing::stack(*w, 2, 0.25f);
  const float p3[3] = {5, 0, 2}, p4[3] = {-5, 0, 3}, p5[3] = {-5, 1, 3};
  const auto gone = cellphys::testing::add_sphere(*w, 0.2f, 1.0f, p3);
  const auto a = cellphys::testing::add_sphere(*w, 0.2f, 1.0f, p4), b = cellphys::testing::add_sphere(*w, 0.2f, 2.0f, p5);
  w->add_force("spring", a, gone, {{"stiffness", {10.0f}}});
  w->add_force("spring", a, b, {{"stiffness", {40.0f}}, {"rest_length", {1.0f}}});
  w->remove_body(gone);
  for (int s = 0; s < 70; ++s) w->step();
  const float kick[3] = {2, 0, 9};
  w->apply_impulse(a, kick, w->state(a).position);
  w->step();
  return w;
}

TEST(Snapshot, RecordsWrittenWrongAreRefusedByFieldAndTheWorldKept) {
  std::unique_ptr<World> source = edited_world();
  const std::vector<unsigned char> good = source->snapshot();
  const Layout l = layout_of(good);
  ASSERT_EQ(u32_at(good, l.bodies), 6u);
  ASSERT_EQ(l.forces.size(), 2u);
  ASSERT_GE(u32_at(good, l.groups), 1u) << "the stack should sleep";
  ASSERT_GT(u32_at(good, l.group_contacts[0]), 0u) << "a sleeping group keeps its contacts";
  ASSERT_GT(u32_at(good, l.pairs), 0u) << "the contact memory should hold pairs";
  ASSERT_TRUE(source->is_awake(4));
  ASSERT_FALSE(source->is_awake(1));
  const size_t contact0 = l.group_contacts[0] + 4, pair0 = l.pairs + 4;
  // field offsets in a body record (runtime/ppe/snapshot.cpp)
  constexpr size_t kShape = 4, kScale = 8, kMass = 12, kInertia = 16, kInverse = 40, kPosition = 64, kOrientation = 76,
                   kVelocity = 92, kAngular = 104, kFriction = 116, kGroup = 132;
  const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
  auto param = [&](const char* name) {
    for (const cellphys::gen::ForceInfo& f : cellphys::gen::kForceTable)
      for (uint32_t k = 0; k < f.num_params; ++k)
        if (std::string(f.name) == "spring" && std::string(f.params[k].name) == name) return f.params[k].offset;
    ADD_FAILURE() << "spring has no " << name;
    return 0u;
  };
  struct Case {
    const char* what;
    std::function<void(std::vector<unsigned char>&)> edit;
    const char* error;
  };
  const std::vector<Case> cases = {
      {"NaN position", [&](auto& b) { put_at(b, l.body(4) + kPosition + 4, nan); }, "body 4: position[1] is not finite (nan)"},
      {"infinite position", [&](auto& b) { put_at(b, l.body(2) + kPosition, -inf); }, "body 2: position[0] is not finite (-inf)"},
      {"NaN velocity", [&](auto& b) { put_at(b, l.body(5) + kVelocity + 8, nan); }, "body 5: velocity[2] is not finite"},
      {"infinite angular velocity", [&](auto& b) { put_at(b, l.body(4) + kAngular, inf); },
       "body 4: angular velocity[0] is not finite (inf)"},
      {"quaternion not unit", [&](auto& b) { put_at(b, l.body(1) + kOrientation, 1.5f); },
       "body 1: orientation is not a unit quaternion (norm 1.5)"},
      {"zero quaternion", [&](auto& b) { std::memset(b.data() + l.body(4) + kOrientation, 0, 16); },
       "body 4: orientation is not a unit quaternion (norm 0)"},
      {"NaN quaternion", [&](auto& b) { put_at(b, l.body(4) + kOrientation + 12, nan); }, "body 4: orientation[3] is not finite"},
      {"zero mass", [&](auto& b) { put_at(b, l.body(2) + kMass, 0.0f); }, "body 2: mass is not positive (0)"},
      {"negative mass", [&](auto& b) { put_at(b, l.body(5) + kMass, -2.0f); }, "body 5: mass is not positive (-2)"},
      {"infinite mass", [&](auto& b) { put_at(b, l.body(5) + kMass, inf); }, "body 5: mass is not finite (inf)"},
      {"a principal moment not positive", [&](auto& b) { put_at(b, l.body(1) + kInertia + 8, -0.1f); },
       "body 1: inertia[2] (a principal moment) is not positive (-0.1)"},
      {"NaN inertia", [&](auto& b) { put_at(b, l.body(1) + kInertia + 12, nan); }, "body 1: inertia[3] is not finite"},
      {"inverse inertia not the inverse", [&](auto& b) { put_at(b, l.body(4) + kInverse, 1.0f); },
       "body 4: inverse inertia is not the inverse of its inertia"},
      {"static body with a mass", [&](auto& b) { put_at(b, l.body(0) + kMass, 1.0f); }, "body 0: a static body has a mass"},
      {"static body moving", [&](auto& b) { put_at(b, l.body(0) + kVelocity, 1.0f); }, "body 0: a static body is moving"},
      {"shape index out of range", [&](auto& b) { put_at<uint32_t>(b, l.body(2) + kShape, 77); },
       "body 2: shape 77 does not exist"},
      {"scale not positive", [&](auto& b) { put_at(b, l.body(4) + kScale, 0.0f); }, "body 4: scale is not positive (0)"},
      {"negative friction", [&](auto& b) { put_at(b, l.body(4) + kFriction, -0.5f); }, "body 4: friction is negative (-0.5)"},
      {"flag byte not 0 or 1", [&](auto& b) { b[l.body(3)] = 7; }, "body 3: alive flag is 7, not 0 or 1"},
      {"body count past the file", [&](auto& b) { put_at<uint32_t>(b, l.bodies, 100000); },
       "bodies count 100000 runs past the end"},
      {"force parameter NaN", [&](auto& b) { put_at(b, l.instances[1] + param("stiffness"), nan); },
       "force 1 (spring): stiffness is not finite (nan)"},
      {"force parameter below its bound", [&](auto& b) { put_at(b, l.instances[1] + param("stiffness"), -1.0f); },
       "force 1 (spring): stiffness must be >= 0, is -1"},
      {"live force on a removed body", [&](auto& b) { b[l.forces[0]] = 1; }, "force 0 (spring): body b (body 3) was removed"},
      {"force on a static body", [&](auto& b) { put_at<uint32_t>(b, l.instances[1] - 8, 0); },
       "force 1 (spring): body b (body 0) is static"},
      {"force on a missing body", [&](auto& b) { put_at<uint32_t>(b, l.instances[1] - 12, 9); },
       "force 1 (spring): body a is body 9, which does not exist (6 bodies)"},
      {"force count past the file", [&](auto& b) { put_at<uint32_t>(b, l.forces[0] - 4, 1u << 30); },
       "forces count 1073741824 runs past the end"},
      {"sleeping member awake", [&](auto& b) { b[l.body(1) + 2] = 1; }, "sleeping group 0: member body 1 is awake"},
      {"body in a missing group", [&](auto& b) { put_at<int32_t>(b, l.body(4) + kGroup, 5); },
       "body 4: sleeping group 5 does not exist"},
      {"body naming a group it is not in", [&](auto& b) { put_at<int32_t>(b, l.body(5) + kGroup, 0); b[l.body(5) + 2] = 0; },
       "sleeping group 0: 2 members listed, 3 bodies in it"},
      {"kept contact with a NaN point", [&](auto& b) { put_at(b, contact0 + 8 + 4, nan); },
       "sleeping group 0, contact 0: point[1] is not finite"},
      {"kept contact normal not unit", [&](auto& b) { put_at(b, contact0 + 20, 0.0f), put_at(b, contact0 + 24, 0.0f), put_at(b, contact0 + 28, 0.0f); },
       "sleeping group 0, contact 0: normal is not a unit vector (norm 0)"},
      {"kept contact holding at no depth", [&](auto& b) { put_at(b, contact0 + 64, 0.0f); },
       "sleeping group 0, contact 0: hold is not above 0 (0)"},
      {"kept contact that gravity opens", [&](auto& b) { put_at(b, contact0 + 68, 0.5f); },
       "sleeping group 0, contact 0: fall is above 0 (0.5)"},
      {"kept contact on a missing body", [&](auto& b) { put_at<uint32_t>(b, contact0, 40); },
       "sleeping group 0, contact 0: body a is body 40, which does not exist"},
      {"contact count past the file", [&](auto& b) { put_at<uint32_t>(b, l.group_contacts[0], 1u << 24); },
       "sleeping contacts count 16777216 runs past the end"},
      {"contact memory slip NaN", [&](auto& b) { put_at(b, pair0 + 12, nan); },
       "contact memory of bodies 1 and 2: slip is not finite (nan)"},
      {"contact memory drift NaN", [&](auto& b) { put_at(b, pair0 + 20, nan); },
       "contact memory of bodies 1 and 2: drift[1] is not finite (nan)"},
      {"contact memory held gaps past its points", [&](auto& b) { put_at<uint32_t>(b, pair0 + 28, 1u << 7); },
       "contact memory of bodies 1 and 2: held gaps 128 name a point past its"},
      {"contact memory on a missing body", [&](auto& b) { put_at<uint64_t>(b, pair0, (uint64_t{12} << 32) | 1); },
       "contact memory of bodies 12 and 1: body a is body 12, which does not exist"},
      {"contact memory pair count past the file", [&](auto& b) { put_at<uint32_t>(b, l.pairs, 1u << 20); },
       "contact memory count 1048576 runs past the end"},
  };
  std::unique_ptr<World> current = World::restore(good.data(), good.size());
  const World* const held = current.get();
  const uint64_t hash = current->state_hash();
  for (const Case& c : cases) {
    std::vector<unsigned char> b = good;
    c.edit(b);
    seal(b);
    try {
      current = World::restore(b.data(), b.size());
      ADD_FAILURE() << c.what << ": accepted";
    } catch (const WorldError& e) {
      EXPECT_NE(std::string(e.what()).find(std::string("snapshot: ") + c.error), std::string::npos)
          << c.what << ": " << e.what();
    }
    ASSERT_EQ(current.get(), held) << c.what;
    EXPECT_EQ(current->state_hash(), hash) << c.what << ": the world in hand changed";
  }
  EXPECT_EQ(current->snapshot(), good) << "the world in hand saves what it was restored from";
  EXPECT_EQ(source->snapshot(), good);
}

// The bytes with each contact memory pair as versions before 10 wrote it: no drift, no held gaps.
std::vector<unsigned char> without_pair_drift(std::vector<unsigned char> b) {
  const Layout l = layout_of(b);
  size_t at = l.pairs;
  const uint32_t pairs = u32_at(b, at);
  at += 4;
  for (uint32_t k = 0; k < pairs; ++k) {
    at += 8 + 4 + 4;  // key, sliding, slip
    b.erase(b.begin() + long(at), b.begin() + long(at + 16));
    at += 4 + u32_at(b, at) * 24;  // anchors
  }
  return b;
}

// A snapshot as an older version wrote it: without the setting `name` (its value `bytes` long),
// the settings' count one less, the header's version `version` (its pairs as that version wrote
// them), sealed again.
std::vector<unsigned char> without_setting(std::vector<unsigned char> b, const std::string& name, uint32_t bytes,
                                           uint32_t version) {
  if (version < 10) b = without_pair_drift(std::move(b));
  const auto at = std::search(b.begin() + 32, b.end(), name.begin(), name.end());
  EXPECT_NE(at, b.end()) << name;
  if (at == b.end()) return b;
  const size_t start = size_t(at - b.begin()) - 4, value = start + 4 + name.size();
  uint32_t len = 0;
  std::memcpy(&len, b.data() + value, 4);
  EXPECT_EQ(len, bytes) << name;
  b.erase(b.begin() + long(start), b.begin() + long(value + 4 + len));
  uint32_t count = 0;
  std::memcpy(&count, b.data() + 32, 4);
  put_at<uint32_t>(b, 32, count - 1);
  put_at<uint32_t>(b, 8, version);
  seal(b);
  return b;
}

// The bytes as version `version` would write them, which has the setting `name` they lack:
// refused, naming it.
void expect_missing(std::vector<unsigned char> b, const std::string& name, uint32_t version) {
  put_at<uint32_t>(b, 8, version);
  seal(b);
  try {
    World::restore(b.data(), b.size());
    ADD_FAILURE() << "a version-" << version << " snapshot without " << name << " was accepted";
  } catch (const WorldError& e) {
    EXPECT_NE(std::string(e.what()).find("'" + name + "' is missing"), std::string::npos) << e.what();
  }
}

}  // namespace

// Version 6 had no whole_island_bytes: such a world restores with 0 and splits its big islands
// as it did; a version-7 snapshot keeps the setting.
TEST(Snapshot, Version6WithoutWholeIslandBytesRestoresSplittingBigIslands) {
  World w;
  cellphys::testing::pile_in_bin(w, 300, 0.25f, 1);
  size_t largest = 0;  // until it lands in one island too big for the local store
  for (int i = 0; i < 300 && largest <= w.settings().local_store_bytes; ++i) largest = w.step().local_store_peak_bytes;
  ASSERT_GT(largest, w.settings().local_store_bytes);
  const std::vector<unsigned char> now = w.snapshot();
  EXPECT_EQ(World::restore(now.data(), now.size())->settings().whole_island_bytes, w.settings().whole_island_bytes);
  std::vector<unsigned char> b = without_setting(now, "whole_island_bytes", 8, 6);
  auto old = World::restore(b.data(), b.size());
  EXPECT_EQ(old->settings().whole_island_bytes, 0u);
  EXPECT_GT(old->step().decoupled_islands, 0u);
  EXPECT_EQ(w.step().decoupled_islands, 0u);
  expect_missing(b, "whole_island_bytes", 7);
}

// Version 7 had no joint.projection: such a world restores with 0 and steps on as it did, its
// joints unprojected; a version-8 snapshot keeps the setting, and one without it is refused.
TEST(Snapshot, Version7WithoutJointProjectionRestoresUnprojected) {
  using cellphys::ppe::BodyDesc;
  using cellphys::ppe::BodyId;
  using cellphys::ppe::kWorldBody;
  World w;
  const float half[3] = {0.2f, 0.2f, 0.2f};
  BodyDesc d;
  d.shape = w.shapes().add_box(half);
  d.mass = 5;
  d.state.position[2] = 2;
  const BodyId a = w.add_body(d);
  const float pivot[3] = {0.05f, 0, 2.3f};  // 5 cm off the box's joint point: the first step projects it
  w.add_force("cone_twist", a, kWorldBody,
              {{"point_a", {0, 0, 0.3f}}, {"point_b", {pivot[0], pivot[1], pivot[2]}}, {"axis_a", {0, 0, 1}},
               {"axis_b", {0, 0, 1}}, {"ref_a", {1, 0, 0}}, {"ref_b", {1, 0, 0}}});
  const std::vector<unsigned char> now = w.snapshot();
  EXPECT_EQ(World::restore(now.data(), now.size())->settings().joint_projection, w.settings().joint_projection);
  std::vector<unsigned char> b = without_setting(now, "joint.projection", 4, 7);
  auto old = World::restore(b.data(), b.size());
  EXPECT_EQ(old->settings().joint_projection, 0.0f);
  EXPECT_EQ(old->step().projected_joints, 0u);
  EXPECT_EQ(w.step().projected_joints, 1u);
  expect_missing(b, "joint.projection", 8);
}

// Version 8 had no contact.joined_hold_depth: such a world restores with contact.hold_depth's
// value there, so every contact holds as it did; a version-9 snapshot keeps the setting, and one
// without it is refused.
TEST(Snapshot, Version8WithoutJoinedHoldDepthHoldsEveryContactAtTheHoldDepth) {
  World w;
  cellphys::testing::ground_plane(w, 0.6f);
  const float up[4] = {1, 0, 0, 0}, at[3] = {0, 0, 1.2f};
  cellphys::testing::add_ragdoll(w, 1.8f, 70.0f, at, up);
  for (int i = 0; i < 30; ++i) w.step();
  const std::vector<unsigned char> now = w.snapshot();
  EXPECT_EQ(World::restore(now.data(), now.size())->settings().contact_joined_hold_depth,
            w.settings().contact_joined_hold_depth);
  ASSERT_NE(w.settings().contact_joined_hold_depth, w.settings().globals.contact_hold_depth);
  std::vector<unsigned char> b = without_setting(now, "contact.joined_hold_depth", 4, 8);
  auto old = World::restore(b.data(), b.size());
  EXPECT_EQ(old->settings().contact_joined_hold_depth, w.settings().globals.contact_hold_depth);
  expect_missing(b, "contact.joined_hold_depth", 9);
}
