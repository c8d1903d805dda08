// World snapshots: save -> restore -> continue equals an uninterrupted run bit for bit, and a
// damaged snapshot is refused with the reason.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>

#include "runtime/ppe/world.h"
#include "runtime/scene/scene.h"
#include "testing/scenes.h"

namespace {

using cellphys::ppe::World;
using cellphys::ppe::WorldError;

std::string scene_file(const char* name) { return std::string(CELLPHYS_SCENES_DIR) + "/" + name + ".json"; }

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

TEST(Snapshot, World1000WithSleepersAndHullsResumesBitForBit) {
  auto built = cellphys::scene::build_world(cellphys::scene::load_scene(scene_file("world1000")));
  World& w = *built.world;
  for (int s = 0; s < 50; ++s) w.step();
  ASSERT_GT(w.last_stats().sleeping_bodies, 0u) << "the snapshot should hold sleeping groups";
  check_resume(w, 0, 25);
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

}  // namespace
