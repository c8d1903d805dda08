// Compound bodies (docs/scene-format.md, "Compounds"): one body of several convex parts.
// Mass properties against shapes whose closed form or hull integration is independent of the
// parts (two boxes side by side are one box; a turned part is a turned hull); a table on four
// legs and an L-shaped block resting as their parts would; the pair order not mattering to a
// bit; rays and overlap tests finding the parts; bad parts refused by name; scene files and
// snapshots carrying them.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <utility>
#include <string>
#include <vector>

#include "runtime/ppe/mass_properties.h"
#include "runtime/ppe/world.h"
#include "runtime/scene/scene.h"
#include "runtime/spu/narrow_phase.h"

namespace {

using namespace cellphys::ppe;
namespace spu = cellphys::spu;

CompoundPart part(uint32_t shape, float x, float y, float z, const float q[4] = nullptr, float scale = 1.0f) {
  CompoundPart p;
  p.shape = shape;
  p.position[0] = x, p.position[1] = y, p.position[2] = z;
  if (q) std::copy(q, q + 4, p.orientation);
  p.scale = scale;
  return p;
}

// Two unit cubes side by side along x are one 2 x 1 x 1 box: its volume, its inertia about the
// common centre, and the shift that centre is from the input origin.
TEST(CompoundBodies, MassPropertiesAreTheWholeShapes) {
  ShapeDictionary d;
  const float half[3] = {0.5f, 0.5f, 0.5f}, whole[3] = {1.0f, 0.5f, 0.5f};
  const uint32_t cube = d.add_box(half), box = d.add_box(whole);
  const CompoundPart parts[2] = {part(cube, 1.0f, 3.0f, 0.0f), part(cube, 2.0f, 3.0f, 0.0f)};
  CompoundInfo info;
  const uint32_t c = d.add_compound(parts, 2, &info);
  EXPECT_FLOAT_EQ(info.shift[0], 1.5f);
  EXPECT_FLOAT_EQ(info.shift[1], 3.0f);
  const MassProperties mc = mass_properties_from_density(d, c, 1.0f, 700.0f), mb = mass_properties_from_density(d, box, 1.0f, 700.0f);
  EXPECT_NEAR(mc.mass, mb.mass, 1e-9 * mb.mass);
  for (int k = 0; k < 6; ++k) EXPECT_NEAR(mc.inertia[k], mb.inertia[k], 1e-9 * mb.inertia[0]) << k;
  for (double x : mc.center_of_mass) EXPECT_NEAR(x, 0.0, 1e-12) << "stored parts are centred";

  // A part turned 30 degrees about z and scaled 1.5: the hull of that box's corners, turned and
  // scaled, integrated as a polyhedron.
  const double a = 0.5235987755982988;
  const float q[4] = {float(std::cos(a / 2)), 0.0f, 0.0f, float(std::sin(a / 2))};
  const float h[3] = {0.4f, 0.2f, 0.1f};
  const uint32_t small = d.add_box(h);
  const CompoundPart turned[1] = {part(small, 0.0f, 0.0f, 0.0f, q, 1.5f)};
  std::vector<float> corners;
  for (int i = 0; i < 8; ++i) {
    const double x = 1.5 * (i & 1 ? h[0] : -h[0]), y = 1.5 * (i & 2 ? h[1] : -h[1]), z = 1.5 * (i & 4 ? h[2] : -h[2]);
    corners.insert(corners.end(), {float(std::cos(a) * x - std::sin(a) * y), float(std::sin(a) * x + std::cos(a) * y), float(z)});
  }
  const MassProperties mt = mass_properties_from_density(d, d.add_compound(turned, 1), 1.0f, 1.0f);
  const MassProperties mh = mass_properties_from_density(d, d.add_hull(corners.data(), 8), 1.0f, 1.0f);
  EXPECT_NEAR(mt.volume, mh.volume, 1e-5 * mh.volume);
  for (int k = 0; k < 6; ++k) EXPECT_NEAR(mt.inertia[k], mh.inertia[k], 1e-4 * mh.inertia[0]) << k;
  EXPECT_GT(std::fabs(mt.inertia[3]), 1e-3 * mt.inertia[0]) << "the turn gives a product of inertia";
}

BodyId ground(World& w) {
  const float up[3] = {0, 0, 1};
  BodyDesc g;
  g.shape = w.shapes().add_plane(up, 0.0f);
  g.is_static = true;
  return w.add_body(g);
}

// A table (a top on four legs) dropped on the ground stands on its legs, level, where it fell;
// an L of two boxes lands and rests on its long side; both as still as the boxes they are made of.
TEST(CompoundBodies, ATableStandsOnItsLegs) {
  World w;
  ground(w);
  const float top_h[3] = {0.6f, 0.4f, 0.03f}, leg_h[3] = {0.03f, 0.03f, 0.35f};
  const uint32_t top = w.shapes().add_box(top_h), leg = w.shapes().add_box(leg_h);
  std::vector<CompoundPart> parts = {part(top, 0, 0, 0.73f)};
  for (float x : {-0.55f, 0.55f})
    for (float y : {-0.35f, 0.35f}) parts.push_back(part(leg, x, y, 0.35f));
  CompoundInfo info;
  BodyDesc t;
  t.shape = w.shapes().add_compound(parts.data(), int(parts.size()), &info);
  t.mass = 20.0f;
  t.state.position[0] = 1.0f, t.state.position[1] = -2.0f, t.state.position[2] = info.shift[2] + 0.2f;
  const BodyId table = w.add_body(t);

  const float long_h[3] = {0.5f, 0.1f, 0.1f}, short_h[3] = {0.1f, 0.1f, 0.3f};
  const std::vector<CompoundPart> l = {part(w.shapes().add_box(long_h), 0.0f, 0.0f, 0.1f),
                                       part(w.shapes().add_box(short_h), -0.4f, 0.0f, 0.5f)};
  CompoundInfo linfo;
  BodyDesc b;
  b.shape = w.shapes().add_compound(l.data(), 2, &linfo);
  b.mass = 5.0f;
  b.state.position[0] = -2.0f, b.state.position[1] = linfo.shift[1], b.state.position[2] = linfo.shift[2] + 0.5f;
  const BodyId ell = w.add_body(b);
  for (int s = 0; s < 180; ++s) w.step();
  const BodyState ts = w.state(table);
  EXPECT_NEAR(ts.position[2], info.shift[2], 2e-3) << "the legs' feet on the ground";
  EXPECT_NEAR(ts.position[0], 1.0f, 1e-3);
  EXPECT_NEAR(ts.position[1], -2.0f, 1e-3);
  EXPECT_GT(std::fabs(ts.orientation[0]), 0.99999f) << "level";
  const BodyState ls = w.state(ell);
  EXPECT_NEAR(ls.position[2], linfo.shift[2], 2e-3) << "the L rests on its long side";
  EXPECT_GT(std::fabs(ls.orientation[0]), 0.9999f);
  EXPECT_LT(std::hypot(ls.velocity[0], ls.velocity[2]) + std::hypot(ts.velocity[0], ts.velocity[2]), 1e-2);
}

// collide(a, b) and collide(b, a) give the same contacts with the normals negated, bit for bit,
// for a compound against a box and against another compound.
TEST(CompoundBodies, PairOrderDoesNotChangeABit) {
  ShapeDictionary d;
  const float h[3] = {0.3f, 0.2f, 0.1f};
  const uint32_t box = d.add_box(h), ball = d.add_sphere(0.15f);
  const float q[4] = {0.9f, 0.1f, 0.3f, 0.2f};
  const CompoundPart parts[3] = {part(box, 0, 0, 0), part(ball, 0.35f, 0, 0.05f), part(box, -0.2f, 0.1f, 0.2f, q, 0.5f)};
  const uint32_t c = d.add_compound(parts, 3);
  spu::Pose pa, pb, pc;
  pa.position[2] = 0.05f, pa.orientation[0] = 0.98f, pa.orientation[1] = 0.199f;
  pb.position[0] = 0.2f, pb.position[2] = -0.2f;
  pc.position[0] = 0.3f, pc.position[1] = 0.05f, pc.position[2] = 0.25f;
  for (const auto& [other, po] : {std::pair{box, pb}, std::pair{c, pc}}) {
    spu::ContactPoint ab[4], ba[4];
    const int n = spu::collide(d.view(c), pa, d.view(other), po, 0.01f, ab);
    ASSERT_EQ(n, spu::collide(d.view(other), po, d.view(c), pa, 0.01f, ba));
    ASSERT_GT(n, 0);
    for (int i = 0; i < n; ++i) {
      EXPECT_EQ(0, std::memcmp(ab[i].point, ba[i].point, sizeof ab[i].point));
      for (int k = 0; k < 3; ++k) EXPECT_EQ(ab[i].normal[k], -ba[i].normal[k]);
      EXPECT_EQ(ab[i].penetration, ba[i].penetration);
    }
  }
}

// Rays and overlap tests meet the parts, not the space between them.
TEST(CompoundBodies, QueriesMeetTheParts) {
  World w;
  const uint32_t ball = w.shapes().add_sphere(0.25f);
  const CompoundPart parts[2] = {part(ball, -1.0f, 0, 0), part(ball, 1.0f, 0, 0)};
  BodyDesc b;
  b.shape = w.shapes().add_compound(parts, 2);
  b.mass = 1.0f;
  b.state.position[2] = 2.0f;
  const BodyId dumbbell = w.add_body(b);
  const float down[3] = {0, 0, -1};
  const float over_part[3] = {1.0f, 0.0f, 5.0f}, over_gap[3] = {0.0f, 0.0f, 5.0f};
  const auto hit = w.ray_cast(over_part, down, 10.0f);
  ASSERT_TRUE(hit.has_value());
  EXPECT_EQ(hit->body, dumbbell);
  EXPECT_NEAR(hit->distance, 5.0f - 2.0f - 0.25f, 1e-5);
  EXPECT_FALSE(w.ray_cast(over_gap, down, 10.0f).has_value()) << "between the parts";
  const float at_part[3] = {-1.2f, 0.0f, 2.0f}, at_gap[3] = {0.0f, 0.0f, 2.0f};
  EXPECT_EQ(w.overlap_sphere(at_part, 0.1f), std::vector<BodyId>{dumbbell});
  EXPECT_TRUE(w.overlap_sphere(at_gap, 0.3f).empty());
}

TEST(CompoundBodies, BadPartsAreRefusedByName) {
  ShapeDictionary d;
  const float up[3] = {0, 0, 1};
  const uint32_t ball = d.add_sphere(0.2f), plane = d.add_plane(up, 0.0f);
  auto refused = [&](std::vector<CompoundPart> parts, const std::string& says) {
    try {
      d.add_compound(parts.data(), int(parts.size()));
      ADD_FAILURE() << "accepted: " << says;
    } catch (const ShapeError& e) {
      EXPECT_NE(std::string(e.what()).find(says), std::string::npos) << e.what();
    }
  };
  refused({part(ball, 0, 0, 0), part(9, 0, 0, 0)}, "compound: part 1: shape 9 does not exist");
  refused({part(plane, 0, 0, 0)}, "compound: part 0: a plane cannot be a part");
  const float zero[4] = {0, 0, 0, 0};
  refused({part(ball, 0, 0, 0, zero)}, "compound: part 0: orientation is zero");
  refused({part(ball, NAN, 0, 0)}, "compound: part 0: position is not finite");
  refused({part(ball, 0, 0, 0, nullptr, -1.0f)}, "scale must be positive");
  refused({}, "compound: needs 1 to 64 parts, got 0");
  const uint32_t one = d.add_compound(std::vector<CompoundPart>{part(ball, 0, 0, 0)}.data(), 1);
  refused({part(one, 0, 0, 0)}, "a compound cannot be a part");
}

// A scene file names each part's shape; written and read back equal; built, stepped, saved and
// restored, it steps on bit for bit.
TEST(CompoundBodies, SceneFilesAndSnapshotsCarryCompounds) {
  const std::string text = R"({
    "shapes": [
      {"name": "ground", "type": "plane", "normal": [0, 0, 1]},
      {"name": "seat", "type": "box", "half_extents": [0.25, 0.25, 0.03]},
      {"name": "leg", "type": "capsule", "radius": 0.03, "half_height": 0.2},
      {"name": "chair", "type": "compound", "parts": [
        {"shape": "seat", "position": [0, 0, 0.45]},
        {"shape": "leg", "position": [-0.2, -0.2, 0.2]}, {"shape": "leg", "position": [0.2, -0.2, 0.2]},
        {"shape": "leg", "position": [-0.2, 0.2, 0.2]}, {"shape": "leg", "position": [0.2, 0.2, 0.2]},
        {"shape": "seat", "position": [0, 0.24, 0.75], "orientation": [0.7071068, 0.7071068, 0, 0], "scale": 0.9}]}
    ],
    "bodies": [
      {"id": "ground", "shape": "ground", "static": true},
      {"id": "chair", "shape": "chair", "mass": 6, "position": [0, 0, 0.8]}
    ]
  })";
  const cellphys::scene::SceneDesc s = cellphys::scene::parse_scene(text, "chair.json");
  const cellphys::scene::SceneDesc back = cellphys::scene::parse_scene(cellphys::scene::write_scene(s), "written");
  EXPECT_TRUE(back.shapes == s.shapes);
  cellphys::scene::BuiltScene built = cellphys::scene::build_world(s);
  World& w = *built.world;
  for (int k = 0; k < 90; ++k) w.step();
  EXPECT_GT(std::fabs(w.state(built.bodies[1]).orientation[0]), 0.999f) << "the chair stands";
  const std::vector<unsigned char> snap = w.snapshot();
  auto r = World::restore(snap.data(), snap.size());
  for (int k = 0; k < 30; ++k) w.step(), r->step();
  EXPECT_EQ(w.state_hash(), r->state_hash());
  try {
    cellphys::scene::build_world(cellphys::scene::parse_scene(
        R"({"shapes": [{"name": "c", "type": "compound", "parts": [{"shape": "later"}]}, {"name": "later", "type": "sphere", "radius": 1}]})",
        "order.json"));
    ADD_FAILURE() << "a part naming a later shape accepted";
  } catch (const cellphys::scene::SceneError& e) {
    EXPECT_NE(std::string(e.what()).find("shapes[0].parts[0].shape"), std::string::npos) << e.what();
  }
}

}  // namespace
