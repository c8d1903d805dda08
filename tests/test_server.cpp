// `cellphys serve` as a process on a free loopback port, talked to with a real WebSocket client
// (Boost.Beast's, tests/support/ws_client.h): the join's shape dictionary and bodies against the
// scene built here, tick updates that carry only what changed (sleeping bodies are not resent),
// region interest, every command, refused commands naming their field with the world unchanged,
// the token, rate limiting, worlds that fail or are loaded beside healthy ones, a client that
// stops reading, record and replay, and /metrics. Plus, in process, the quantisation error.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <set>
#include <string>
#include <thread>

#include <nlohmann/json.hpp>

#include "runtime/scene/scene.h"
#include "runtime/spu/island_image.h"
#include "server/debug_encoder.h"
#include "server/message_decode.h"
#include "server/quantise.h"
#include "server/spawn_shapes.h"
#include "server/state_encoder.h"
#include "tests/support/serve_process.h"
#include "tests/support/server_client.h"

namespace {

namespace fs = std::filesystem;
namespace p = cellphys::server::protocol;
using cellphys::test::ServeProcess;
using cellphys::test::ServerClient;
using json = nlohmann::json;
using namespace std::chrono_literals;

const std::string kExe = CELLPHYS_EXE;
const std::string kScenes = CELLPHYS_SCENES_DIR;

ServeProcess serve(std::vector<std::string> args) { return ServeProcess(kExe, std::move(args), kScenes); }

json metrics(const ServeProcess& s) {
  const auto [status, body] = cellphys::test::http_get(s.port(), "/metrics");
  EXPECT_EQ(status, 200);
  return json::parse(body);
}

json world_metrics(const ServeProcess& s, const std::string& name) {
  const json all = metrics(s);
  for (const json& w : all["worlds"])
    if (w["name"] == name) return w;
  ADD_FAILURE() << "no world " << name << " in /metrics";
  return json::object();
}

p::Spawn spawn_box(float x, float y, float z) {
  p::Spawn s{};
  s.shape = 1;  // pile65's box
  s.scale = 1;
  s.mass = 1;
  s.friction = 0.5f;
  s.position[0] = x;
  s.position[1] = y;
  s.position[2] = z;
  s.orientation[0] = 1;
  return s;
}

// The world argument of a client that reads protocol revision 4 (meshes, height fields,
// compounds): ServerClient puts it after "/ws?world=".
std::string reading_revision_4(const std::string& world) { return world + "&revision=4"; }

// A scene file's world as `cellphys serve` builds it, for comparison: with the shapes it adds
// for spawning.
cellphys::scene::BuiltScene served(const std::string& file) {
  cellphys::scene::BuiltScene b = cellphys::scene::build_world(cellphys::scene::load_scene(file));
  cellphys::server::add_spawn_shapes(b.world->shapes());
  return b;
}
cellphys::scene::BuiltScene built(const std::string& name) { return served(kScenes + "/" + name + ".json"); }

TEST(Server, JoinCarriesTheShapeDictionaryThenTicksCarryOnlyWhatChanged) {
  ServeProcess s = serve({"pile65"});
  ServerClient c(s.port(), "pile65");
  ASSERT_TRUE(c.until([&] { return c.joins == 1; }));
  const auto scene = built("pile65");
  const cellphys::ppe::World& w = *scene.world;
  EXPECT_EQ(c.join.world, "pile65");
  EXPECT_EQ(c.join.head.flags & p::kJoinCanCommand, 0u);  // no token given
  ASSERT_EQ(c.join.shapes.size(), w.shapes().size());
  for (uint32_t i = 0; i < w.shapes().size(); ++i) {
    EXPECT_EQ(c.join.shapes[i].type, static_cast<uint32_t>(w.shapes().type(i)));
    if (w.shapes().type(i) == cellphys::spu::ShapeType::box) {
      for (int k = 0; k < 3; ++k) EXPECT_EQ(c.join.shapes[i].params[k], w.shapes().view(i).half_extents[k]);
    }
  }
  ASSERT_EQ(c.join.bodies.size(), w.num_bodies());
  for (const p::BodyFull& b : c.join.bodies) {
    EXPECT_EQ(b.shape, w.shape(b.id));
    EXPECT_EQ(b.scale, w.scale(b.id));
  }
  // Ticks follow, the step advancing; every moved body's state differs from what was sent before.
  ASSERT_TRUE(c.until([&] { return c.ticks.size() >= 20; }));
  EXPECT_GT(c.step, c.join.head.step);
  size_t moved = 0;
  for (const auto& t : c.ticks) moved += t.moved.size();
  EXPECT_GT(moved, 0u);  // the pile is falling into its bin
  EXPECT_EQ(c.last_problem, "");
}

// Level geometry: a mesh and a height field go out as their triangles, each as a hull's face of
// 3, so a client draws them with a hull's code; the height field's triangles are its grid's as
// the scene format describes it (row i along y, column j along x, centred on the body origin).
// Neither can be spawned.
TEST(Server, MeshesAndHeightFieldsAreSentAsTheirTriangles) {
  const fs::path dir = fs::temp_directory_path() / ("cellphys_surfaces_" + std::to_string(getpid()));
  fs::create_directories(dir);
  const int rows = 4, columns = 5;
  const float spacing[2] = {0.5f, 0.75f};
  json heights = json::array();
  for (int i = 0; i < rows; ++i)
    for (int j = 0; j < columns; ++j) heights.push_back(0.125 * i - 0.0625 * j + 0.25 * ((i * j) % 3));
  // A pyramid: four sides and a base of two triangles, counter-clockwise from outside.
  const std::vector<float> pv = {-0.5f, -0.5f, 0, 0.5f, -0.5f, 0, 0.5f, 0.5f, 0, -0.5f, 0.5f, 0, 0, 0, 0.75f};
  const std::vector<int> pt = {0, 1, 4, 1, 2, 4, 2, 3, 4, 3, 0, 4, 0, 2, 1, 0, 3, 2};
  json verts = json::array(), tris = json::array();
  for (size_t k = 0; k < pv.size(); k += 3) verts.push_back({pv[k], pv[k + 1], pv[k + 2]});
  for (size_t k = 0; k < pt.size(); k += 3) tris.push_back({pt[k], pt[k + 1], pt[k + 2]});
  const json scene = {
      {"shapes",
       {{{"name", "ball"}, {"type", "sphere"}, {"radius", 0.2}},
        {{"name", "terrain"}, {"type", "height_field"}, {"rows", rows}, {"columns", columns},
         {"spacing", {spacing[0], spacing[1]}}, {"heights", heights}},
        {{"name", "pyramid"}, {"type", "mesh"}, {"vertices", verts}, {"triangles", tris}}}},
      {"bodies",
       {{{"id", "terrain"}, {"shape", "terrain"}, {"static", true}, {"position", {0.5, -0.25, 0}}},
        {{"id", "pyramid"}, {"shape", "pyramid"}, {"static", true}, {"position", {3, 0, 0}}},
        {{"id", "ball"}, {"shape", "ball"}, {"mass", 1.0}, {"position", {0.5, -0.25, 1.5}}}}}};
  const fs::path file = dir / "surfaces.json";
  std::ofstream(file) << scene.dump();
  const auto built_scene = served(file.string());
  const cellphys::ppe::World& w = *built_scene.world;

  ServeProcess s = serve({file.string()});
  ServerClient c(s.port(), reading_revision_4("surfaces"), s.token());
  ASSERT_TRUE(c.until([&] { return c.joins == 1 && c.ticks.size() >= 5; }));
  EXPECT_EQ(c.last_problem, "");
  ASSERT_EQ(c.join.shapes.size(), w.shapes().size());
  using cellphys::spu::ShapeType;
  // A triangle as its three vertex positions, rotated to start at the smallest: the winding
  // kept, the order of the triangles and the numbering of the vertices not.
  using Tri = std::array<std::array<float, 3>, 3>;
  auto triangle = [](const float* v, const uint32_t* t) {
    Tri r;
    for (int k = 0; k < 3; ++k) r[k] = {v[3 * t[k]], v[3 * t[k] + 1], v[3 * t[k] + 2]};
    std::rotate(r.begin(), std::min_element(r.begin(), r.end()), r.end());
    return r;
  };
  int surfaces = 0;
  for (uint32_t i = 0; i < w.shapes().size(); ++i) {
    const ShapeType type = w.shapes().type(i);
    const p::ShapeRecord& r = c.join.shapes[i];
    EXPECT_EQ(r.type, static_cast<uint32_t>(type));
    if (!cellphys::spu::is_triangle_surface(type)) continue;
    ++surfaces;
    SCOPED_TRACE(cellphys::spu::shape_type_name(type));
    const cellphys::spu::MeshView& m = w.shapes().view(i).mesh;
    ASSERT_EQ(r.num_vertices, uint32_t(m.num_vertices));
    ASSERT_EQ(r.num_faces, uint32_t(m.num_triangles));
    ASSERT_EQ(r.num_face_vertices, 3 * r.num_faces);
    const std::vector<float>& v = c.join.vertices[i];
    const std::vector<uint32_t>& start = c.join.face_start[i];
    const std::vector<uint32_t>& loops = c.join.face_vertices[i];
    ASSERT_EQ(v.size(), 3 * size_t(m.num_vertices));
    ASSERT_EQ(start.size(), size_t(m.num_triangles) + 1);
    EXPECT_TRUE(std::equal(v.begin(), v.end(), m.vertices));
    for (uint32_t f = 0; f <= r.num_faces; ++f) EXPECT_EQ(start[f], 3 * f);
    EXPECT_TRUE(std::equal(loops.begin(), loops.end(), m.triangles, [](uint32_t a, int32_t b) { return int64_t(a) == b; }));
    // The triangles against the scene's own numbers.
    std::multiset<Tri> sent, want;
    for (uint32_t f = 0; f < r.num_faces; ++f) sent.insert(triangle(v.data(), &loops[3 * f]));
    if (type == ShapeType::mesh) {
      for (size_t k = 0; k < pt.size(); k += 3) {
        const uint32_t t[3] = {uint32_t(pt[k]), uint32_t(pt[k + 1]), uint32_t(pt[k + 2])};
        want.insert(triangle(pv.data(), t));
      }
    } else {
      std::vector<float> grid;
      for (int row = 0; row < rows; ++row)
        for (int col = 0; col < columns; ++col)
          grid.insert(grid.end(), {float((col - 0.5 * (columns - 1)) * spacing[0]), float((row - 0.5 * (rows - 1)) * spacing[1]),
                                   heights[size_t(row) * columns + col].get<float>()});
      for (int row = 0; row + 1 < rows; ++row)
        for (int col = 0; col + 1 < columns; ++col) {
          const uint32_t a = row * columns + col, b = a + 1, d = a + columns, e = d + 1;
          const uint32_t t0[3] = {a, b, e}, t1[3] = {a, e, d};
          want.insert(triangle(grid.data(), t0));
          want.insert(triangle(grid.data(), t1));
        }
      EXPECT_EQ(want.size(), size_t(2 * (rows - 1) * (columns - 1)));
    }
    EXPECT_TRUE(sent == want) << sent.size() << " triangles sent, " << want.size() << " in the scene";
    // Neither can be spawned; the world is unchanged.
    p::Spawn sp = spawn_box(0, 0, 3);
    sp.shape = i;
    const uint32_t seq = c.command(p::Type::spawn, sp);
    EXPECT_FALSE(c.answer(seq));
    EXPECT_EQ(c.errors[seq].field, "spawn.shape");
    EXPECT_NE(c.errors[seq].reason.find(cellphys::spu::shape_type_name(type)), std::string::npos) << c.errors[seq].reason;
  }
  EXPECT_EQ(surfaces, 2);
  EXPECT_EQ(world_metrics(s, "surfaces")["bodies"], 1);  // the ball: nothing was spawned
  // A client that gives no revision (one older than 4) is told, not sent a join it would misread.
  ServerClient old(s.port(), "surfaces");
  EXPECT_FALSE(old.until([&] { return old.joins > 0; }, 3s));
  ASSERT_EQ(old.errors.count(0), 1u);
  EXPECT_EQ(old.errors[0].field, "revision");
  EXPECT_NE(old.errors[0].reason.find("height_field (shape 1)"), std::string::npos) << old.errors[0].reason;
  for (const p::BodyFull& b : c.join.bodies)
    if (cellphys::spu::is_triangle_surface(w.shapes().type(b.shape))) {
      EXPECT_NE(b.flags & p::kBodyStatic, 0u);
    }
  fs::remove_all(dir);
}

// Revision 4: a compound goes out as its ShapeRecord (type 7, num_vertices its parts) and its
// parts, each naming an earlier shape of the dictionary, at the pose and scale the world holds
// (re-centred on the compound's centre of mass), bit for bit. A client that reads an older
// revision gets an error naming the revision and the compound, then the connection closes;
// it never gets the join.
TEST(Server, CompoundsAreSentAsTheirPartsAndOlderClientsAreTold) {
  const fs::path dir = fs::temp_directory_path() / ("cellphys_compounds_" + std::to_string(getpid()));
  fs::create_directories(dir);
  const double top_z = 0.74, leg_x = 0.5, leg_y = 0.3, leg_z = 0.35;
  const json scene = {
      {"shapes",
       {{{"name", "ground"}, {"type", "plane"}, {"normal", {0, 0, 1}}},
        {{"name", "top"}, {"type", "box"}, {"half_extents", {0.6, 0.4, 0.04}}},
        {{"name", "leg"}, {"type", "box"}, {"half_extents", {0.04, 0.04, 0.35}}},
        {{"name", "ball"}, {"type", "sphere"}, {"radius", 0.1}},
        {{"name", "bar"}, {"type", "capsule"}, {"radius", 0.03}, {"half_height", 0.3}},
        {{"name", "wedge"}, {"type", "hull"}, {"points", {{0, 0, 0}, {0.3, 0, 0}, {0, 0.2, 0}, {0, 0, 0.25}}}},
        {{"name", "table"}, {"type", "compound"}, {"parts",
          {{{"shape", "top"}, {"position", {0, 0, top_z}}},
           {{"shape", "leg"}, {"position", {-leg_x, -leg_y, leg_z}}}, {{"shape", "leg"}, {"position", {leg_x, -leg_y, leg_z}}},
           {{"shape", "leg"}, {"position", {-leg_x, leg_y, leg_z}}}, {{"shape", "leg"}, {"position", {leg_x, leg_y, leg_z}}}}}},
        // Turned (a quaternion not quite unit: the dictionary normalises it) and scaled parts.
        {{"name", "dumbbell"}, {"type", "compound"}, {"parts",
          {{{"shape", "ball"}, {"position", {0.6, 0, 0}}, {"scale", 1.5}},
           {{"shape", "bar"}, {"position", {1.0, 0, 0}}, {"orientation", {0.7, 0, 0.7, 0}}},
           {{"shape", "ball"}, {"position", {1.4, 0, 0}}, {"scale", 1.5}}}}},
        {{"name", "lamp"}, {"type", "compound"}, {"parts",
          {{{"shape", "wedge"}, {"position", {0, 0, 0.1}}, {"scale", 2}}, {{"shape", "bar"}, {"position", {0.2, 0.1, 0.5}}}}}}}},
      {"bodies",
       {{{"id", "ground"}, {"shape", "ground"}, {"static", true}},
        {{"id", "table"}, {"shape", "table"}, {"mass", 10.0}, {"position", {0, 0, 0.7}}},
        {{"id", "dumbbell"}, {"shape", "dumbbell"}, {"mass", 4.0}, {"position", {0, 1.5, 0.2}}},
        {{"id", "lamp"}, {"shape", "lamp"}, {"mass", 2.0}, {"position", {2, 0, 0.5}}, {"scale", 0.8}}}}};
  const fs::path file = dir / "compounds.json";
  std::ofstream(file) << scene.dump();
  const auto built_scene = served(file.string());
  const cellphys::ppe::World& w = *built_scene.world;
  const cellphys::ppe::ShapeDictionary& d = w.shapes();
  using cellphys::spu::ShapeType;

  ServeProcess s = serve({file.string()});
  // Older clients: none given (every client before revision 4), and 3 said.
  for (const std::string& revision : {std::string(""), std::string("&revision=3")}) {
    SCOPED_TRACE("revision: '" + revision + "'");
    ServerClient old(s.port(), "compounds" + revision, s.token());
    EXPECT_FALSE(old.until([&] { return old.joins > 0; }, 3s));
    EXPECT_EQ(old.joins, 0);
    EXPECT_TRUE(old.ws().closed() && !old.ws().timed_out()) << "the server closes the connection";
    ASSERT_EQ(old.errors.count(0), 1u);
    const cellphys::server::ErrorMessage& e = old.errors[0];
    EXPECT_EQ(e.head.code, uint16_t(p::ErrorCode::invalid));
    EXPECT_EQ(e.head.command_type, uint16_t(p::Type::join));
    EXPECT_EQ(e.field, "revision");
    EXPECT_NE(e.reason.find("a compound (shape 6)"), std::string::npos) << e.reason;
    EXPECT_NE(e.reason.find("revision=4"), std::string::npos) << e.reason;
    EXPECT_NE(e.reason.find(revision.empty() ? "gave no revision" : "reads revision 3"), std::string::npos) << e.reason;
  }
  EXPECT_THROW(cellphys::test::WsClient(s.port(), "/ws?world=compounds&revision=four"), std::exception);

  ServerClient c(s.port(), reading_revision_4("compounds"), s.token());
  ASSERT_TRUE(c.until([&] { return c.joins == 1 && c.ticks.size() >= 3; }));
  EXPECT_EQ(c.last_problem, "");
  EXPECT_EQ(c.join.head.revision, 5u);
  ASSERT_EQ(c.join.shapes.size(), d.size());
  ASSERT_EQ(c.join.parts.size(), d.size());
  int compounds = 0;
  for (uint32_t i = 0; i < d.size(); ++i) {
    const p::ShapeRecord& r = c.join.shapes[i];
    EXPECT_EQ(r.type, static_cast<uint32_t>(d.type(i)));
    if (d.type(i) != ShapeType::compound) {
      EXPECT_TRUE(c.join.parts[i].empty());
      continue;
    }
    ++compounds;
    SCOPED_TRACE("shape " + std::to_string(i));
    const std::vector<cellphys::ppe::CompoundPart>& held = d.compound_parts(i);
    const cellphys::spu::CompoundView& view = d.view(i).compound;
    const std::vector<p::CompoundPartRecord>& sent = c.join.parts[i];
    EXPECT_EQ(r.num_faces, 0u);
    EXPECT_EQ(r.num_face_vertices, 0u);
    ASSERT_EQ(r.num_vertices, held.size());
    ASSERT_EQ(sent.size(), held.size());
    ASSERT_EQ(size_t(view.num_parts), held.size());
    for (size_t k = 0; k < sent.size(); ++k) {
      const p::CompoundPartRecord& a = sent[k];
      EXPECT_EQ(a.shape, held[k].shape);
      EXPECT_LT(a.shape, i);  // an earlier record: a client resolves it as it reads
      EXPECT_TRUE(cellphys::spu::is_convex(static_cast<ShapeType>(c.join.shapes[a.shape].type)));
      EXPECT_EQ(std::memcmp(a.position, held[k].position, 12), 0);
      EXPECT_EQ(std::memcmp(a.orientation, held[k].orientation, 16), 0);
      EXPECT_EQ(std::memcmp(&a.scale, &held[k].scale, 4), 0);
      // ... and as the narrow phase reads them.
      EXPECT_EQ(view.parts[k].shape, &d.view(a.shape));
      EXPECT_EQ(std::memcmp(a.position, view.parts[k].position, 12), 0);
      EXPECT_EQ(std::memcmp(a.orientation, view.parts[k].orientation, 16), 0);
      EXPECT_EQ(a.scale, view.parts[k].scale);
    }
  }
  EXPECT_EQ(compounds, 3);
  // Against the scene's own numbers: the table's parts are the file's, moved by one shift, its
  // centre of mass at uniform density (the boxes' volume-weighted centre: the top 0.0768 m^3 at
  // z 0.74, each leg 0.00448 m^3 at 0.35).
  const uint32_t table = 6;
  ASSERT_EQ(d.type(table), ShapeType::compound);
  const double vt = 8 * 0.6 * 0.4 * 0.04, vl = 8 * 0.04 * 0.04 * 0.35;
  const double com_z = (vt * top_z + 4 * vl * leg_z) / (vt + 4 * vl);
  const std::vector<p::CompoundPartRecord>& tp = c.join.parts[table];
  const double want[5][3] = {{0, 0, top_z}, {-leg_x, -leg_y, leg_z}, {leg_x, -leg_y, leg_z}, {-leg_x, leg_y, leg_z}, {leg_x, leg_y, leg_z}};
  for (size_t k = 0; k < 5; ++k)
    for (int a = 0; a < 3; ++a) EXPECT_NEAR(tp[k].position[a], want[k][a] - (a == 2 ? com_z : 0.0), 1e-6) << "part " << k << " axis " << a;
  // The dumbbell's bar turned a quarter about y, its quaternion normalised; the balls scaled.
  const std::vector<p::CompoundPartRecord>& dp = c.join.parts[table + 1];
  EXPECT_NEAR(dp[1].orientation[0], std::sqrt(0.5), 1e-6);
  EXPECT_NEAR(dp[1].orientation[2], std::sqrt(0.5), 1e-6);
  EXPECT_EQ(dp[0].scale, 1.5f);
  EXPECT_NEAR(dp[0].position[0], -0.4, 1e-6);  // the centre (x = 1) taken off
  // The bodies carry the compound's index; a compound can be spawned, and enters as one.
  for (const p::BodyFull& b : c.join.bodies) EXPECT_EQ(b.shape, w.shape(b.id));
  p::Spawn sp = spawn_box(0, -2, 1);
  sp.shape = table + 1;
  const uint32_t seq = c.command(p::Type::spawn, sp);
  ASSERT_TRUE(c.answer(seq)) << c.errors[seq].reason;
  const uint32_t spawned = c.acks[seq].result;
  ASSERT_TRUE(c.until([&] { return c.bodies.count(spawned) > 0; }));
  EXPECT_EQ(c.bodies[spawned].shape, table + 1);
  fs::remove_all(dir);
}

// In process: the C++ decoder reads a compound's parts and refuses, before it allocates, a part
// count the message cannot hold, a part naming a later shape or one that is not convex.
TEST(JoinDecoder, ReadsCompoundPartsAndRefusesBadOnes) {
  cellphys::ppe::ShapeDictionary d;
  const float half[3] = {0.5f, 0.25f, 0.125f}, up[3] = {0, 0, 1};
  d.add_sphere(0.3f);
  d.add_plane(up, 0);
  d.add_box(half);
  cellphys::ppe::CompoundPart parts[2];
  parts[0].shape = 0;
  parts[0].position[0] = 1;
  parts[1].shape = 2;
  parts[1].scale = 2;
  parts[1].orientation[0] = 0.6f;
  parts[1].orientation[3] = 0.8f;
  const uint32_t compound = d.add_compound(parts, 2);
  const std::vector<unsigned char> shapes = cellphys::server::encode_shapes(d);
  p::Join j{};
  j.header = {0, uint16_t(p::Type::join), p::kVersion};
  j.num_shapes = uint32_t(d.size());
  j.revision = p::kRevision;
  std::vector<unsigned char> bytes(sizeof j);
  bytes.insert(bytes.end(), shapes.begin(), shapes.end());
  j.header.length = uint32_t(bytes.size());
  std::memcpy(bytes.data(), &j, sizeof j);
  cellphys::server::JoinMessage m;
  ASSERT_EQ(cellphys::server::decode_join(bytes.data(), bytes.size(), m), "");
  ASSERT_EQ(m.parts.size(), 4u);
  ASSERT_EQ(m.parts[compound].size(), 2u);
  for (size_t k = 0; k < 2; ++k) {
    const cellphys::ppe::CompoundPart& held = d.compound_parts(compound)[k];
    EXPECT_EQ(m.parts[compound][k].shape, held.shape);
    EXPECT_EQ(std::memcmp(m.parts[compound][k].position, held.position, 12), 0);
    EXPECT_EQ(std::memcmp(m.parts[compound][k].orientation, held.orientation, 16), 0);
    EXPECT_EQ(m.parts[compound][k].scale, held.scale);
  }
  const size_t record = sizeof(p::Join) + compound * sizeof(p::ShapeRecord), part1 = record + sizeof(p::ShapeRecord) + sizeof(p::CompoundPartRecord);
  auto with = [&](size_t at, uint32_t v) {
    std::vector<unsigned char> b = bytes;
    std::memcpy(b.data() + at, &v, 4);
    cellphys::server::JoinMessage out;
    return cellphys::server::decode_join(b.data(), b.size(), out);
  };
  EXPECT_EQ(with(record + offsetof(p::ShapeRecord, num_vertices), 0x40000000u), "cut in the parts of shape 3");
  EXPECT_EQ(with(record + offsetof(p::ShapeRecord, num_vertices), 0u), "compound shape 3 has no parts");
  EXPECT_EQ(with(part1 + offsetof(p::CompoundPartRecord, shape), 3u), "shape 3 part 1 names shape 3, not an earlier one");
  EXPECT_EQ(with(part1 + offsetof(p::CompoundPartRecord, shape), 1u), "shape 3 part 1 names shape 1, which is not convex");
}

// Revision 3: a client that asks gets a stages message after each state message, for its step,
// with every stage the step times, by name; one that does not ask gets none.
TEST(Server, StagesFollowEachTickWithEveryNamedStage) {
  ServeProcess s = serve({"pile65"});
  ServerClient c(s.port(), "pile65"), quiet(s.port(), "pile65");
  ASSERT_TRUE(c.until([&] { return c.joins == 1; }));
  // Revision 5, to a client that gave none: pile65 holds no shape a client of revision 3 misreads.
  EXPECT_EQ(c.join.head.revision, 5u);
  p::Subscribe sub{};
  sub.flags = p::kSubscribeStages;
  c.subscribe(sub);
  ASSERT_TRUE(c.until([&] { return c.stages.size() >= 30; }));
  ASSERT_TRUE(quiet.until([&] { return quiet.ticks.size() >= 30; }));
  EXPECT_TRUE(quiet.stages.empty());
  for (size_t k = 0; k < c.stages.size(); ++k) {
    const cellphys::server::StagesMessage& m = c.stages[k];
    EXPECT_EQ(m.head.step, c.stages_after[k]);
    ASSERT_EQ(m.stages.size(), std::size(cellphys::ppe::kStageTimeFields));
    float total = -1;
    for (size_t i = 0; i < m.stages.size(); ++i) {
      EXPECT_EQ(m.stages[i].first, cellphys::ppe::kStageTimeFields[i].name);
      EXPECT_TRUE(std::isfinite(m.stages[i].second) && m.stages[i].second >= 0) << m.stages[i].first;
      if (m.stages[i].first == "total") total = m.stages[i].second;
    }
    for (const auto& [name, ms] : m.stages) EXPECT_LE(ms, total) << name << " at step " << m.head.step;
  }
  // A step's stages add up to time spent: the pile's first steps collide and integrate.
  EXPECT_GT(c.stages.back().stages.back().second, 0.0f);
  EXPECT_EQ(c.last_problem, "");
}

TEST(Server, SleepingBodiesAreNotResent) {
  ServeProcess s = serve({"pile65", "--fast"});
  ServerClient c(s.port(), "pile65", s.token());
  // Wait for the pile to fall asleep (stepping as fast as it can).
  ASSERT_TRUE(c.until([&] { return !c.ticks.empty() && c.ticks.back().head.stats.sleeping_bodies == 65; }, 60s));
  c.ticks.clear();
  const uint32_t seq = c.command(p::Type::spawn, spawn_box(6, 0, 2));  // far from the bin
  ASSERT_TRUE(c.answer(seq));
  const uint32_t box = c.acks[seq].result;
  // Until the box has fallen to the ground (its moves carried it there) and 100 ticks came.
  ASSERT_TRUE(c.until([&] { return c.ticks.size() >= 100 && c.bodies.count(box) && c.bodies[box].position[2] < 0.3f; }));
  // (A client that falls behind may first see the box where it landed, in its entered record,
  // so its moves are not counted; that it is at the ground is what the wait above checked.)
  size_t entered = 0;
  for (const auto& t : c.ticks) {
    for (const auto& [id, st] : t.moved) EXPECT_EQ(id, box) << "a sleeping body was resent at step " << t.head.step;
    for (const auto& b : t.entered) entered += b.id == box;
  }
  EXPECT_EQ(entered, 1u);
  EXPECT_EQ(c.last_problem, "");
}

TEST(Server, RegionSubscriptionFiltersBodiesAndReportsThoseThatLeave) {
  ServeProcess s = serve({"pile65"});
  ServerClient c(s.port(), "pile65", s.token());
  ASSERT_TRUE(c.until([&] { return c.joins == 1 && !c.ticks.empty(); }));
  p::Subscribe sub{};
  sub.flags = p::kSubscribeRegion;
  const float lo[3] = {-10, -10, -10}, hi[3] = {0, 10, 10};  // x <= 0
  std::copy(lo, lo + 3, sub.min);
  std::copy(hi, hi + 3, sub.max);
  c.subscribe(sub);
  c.ticks.clear();
  ASSERT_TRUE(c.until([&] { return c.ticks.size() >= 5; }));
  std::set<uint32_t> gone;
  for (const auto& t : c.ticks) gone.insert(t.gone.begin(), t.gone.end());
  EXPECT_GT(gone.size(), 10u);  // about half the pile is at x > 0
  auto inside = [&](const float* x) { return x[0] <= 0; };
  for (const auto& [id, b] : c.bodies)
    if (!(b.flags & p::kBodyUnbounded)) {
      EXPECT_TRUE(inside(b.position)) << "body " << id << " outside the region";
    }
  // A box thrown out of the region is reported gone.
  p::Spawn out = spawn_box(-2, 4, 1);
  out.velocity[0] = 30;
  const uint32_t seq = c.command(p::Type::spawn, out);
  ASSERT_TRUE(c.answer(seq));
  const uint32_t box = c.acks[seq].result;
  c.ticks.clear();
  bool seen = false, left = false;
  ASSERT_TRUE(c.until([&] {
    for (const auto& t : c.ticks) {
      for (const auto& b : t.entered) seen |= b.id == box;
      for (uint32_t id : t.gone) left |= id == box && seen;
      for (const auto& [id, st] : t.moved) EXPECT_TRUE(inside(st.position)) << "body " << id << " sent from outside";
    }
    c.ticks.clear();
    return left;
  }));
  EXPECT_EQ(c.last_problem, "");
}

TEST(Server, EveryCommandWorks) {
  ServeProcess s = serve({"pile65"});
  ServerClient c(s.port(), "pile65", s.token());
  ASSERT_TRUE(c.until([&] { return c.joins == 1; }));
  EXPECT_NE(c.join.head.flags & p::kJoinCanCommand, 0u);
  const size_t scene_bodies = c.join.bodies.size();

  // spawn: acked with the new id, which arrives as an entered body with its shape and pose.
  const uint32_t sp = c.command(p::Type::spawn, spawn_box(6, 0, 0.25f));
  ASSERT_TRUE(c.answer(sp));
  const uint32_t box = c.acks[sp].result;
  ASSERT_TRUE(c.until([&] { return c.bodies.count(box) > 0; }));
  EXPECT_EQ(c.bodies[box].shape, 1u);

  // drag: the box follows a target 2 m up, and falls back once released. (The first pull is
  // 1.5 m of the default spring, 237 N: pulls under about 200 N leave a resting 1 kg box held by
  // its ground contact, an issue of the world's contact reproduced without the server.)
  p::DragStart ds{};
  ds.body = box;
  std::copy(c.bodies[box].position, c.bodies[box].position + 3, ds.point);
  std::copy(c.bodies[box].position, c.bodies[box].position + 3, ds.target);
  ds.target[2] += 1.5f;
  const uint32_t dseq = c.command(p::Type::drag_start, ds);
  ASSERT_TRUE(c.answer(dseq));
  const uint32_t drag = c.acks[dseq].result;
  p::DragMove dm{};
  dm.drag = drag;
  std::copy(ds.target, ds.target + 3, dm.target);
  dm.target[2] += 0.5f;
  ASSERT_TRUE(c.answer(c.command(p::Type::drag_move, dm)));
  ASSERT_TRUE(c.until([&] { return c.bodies[box].position[2] > 2.0f; })) << "box at z " << c.bodies[box].position[2];
  p::DragRelease dr{};
  dr.drag = drag;
  ASSERT_TRUE(c.answer(c.command(p::Type::drag_release, dr)));
  ASSERT_TRUE(c.until([&] { return c.bodies[box].position[2] < 0.5f; }));
  dm.target[2] = 3;  // a released drag is gone
  const uint32_t late = c.command(p::Type::drag_move, dm);
  ASSERT_FALSE(c.answer(late));
  EXPECT_EQ(c.errors[late].field, "drag_move.drag");

  // impulse: 5 N s up on the 1 kg box, settled on the ground again, throws it up at 5 m/s less g dt.
  ASSERT_TRUE(c.until([&] { return c.bodies[box].position[2] < 0.26f && std::fabs(c.bodies[box].velocity[2]) < 0.01f; }));
  std::this_thread::sleep_for(1s);
  ASSERT_TRUE(c.until([&] { return c.ticks.size() > 5; }));
  p::Impulse im{};
  im.body = box;
  im.impulse[2] = 5;
  std::copy(c.bodies[box].position, c.bodies[box].position + 3, im.point);
  ASSERT_TRUE(c.answer(c.command(p::Type::impulse, im)));
  ASSERT_TRUE(c.until([&] { return c.bodies[box].velocity[2] > 4.0f; }));
  ASSERT_TRUE(c.until([&] { return c.bodies[box].position[2] < 0.3f && c.bodies[box].velocity[2] < 0.1f; }));  // lands

  // pause: the step stops; step_once: exactly one step; resume: it goes on.
  ASSERT_TRUE(c.answer(c.control(p::Type::pause)));
  ASSERT_TRUE(c.until([&] { return !c.statuses.empty() && c.statuses.back().head.state == uint32_t(p::WorldState::paused); }));
  const uint64_t paused_at = world_metrics(s, "pile65")["step"];
  std::this_thread::sleep_for(200ms);
  EXPECT_EQ(world_metrics(s, "pile65")["step"], paused_at);
  ASSERT_TRUE(c.answer(c.control(p::Type::step_once)));
  std::this_thread::sleep_for(200ms);
  EXPECT_EQ(world_metrics(s, "pile65")["step"], paused_at + 1);
  ASSERT_TRUE(c.answer(c.control(p::Type::resume)));
  std::this_thread::sleep_for(200ms);
  EXPECT_GT(world_metrics(s, "pile65")["step"], paused_at + 5);

  // remove: reported gone.
  p::Remove rm{};
  rm.body = box;
  ASSERT_TRUE(c.answer(c.command(p::Type::remove, rm)));
  ASSERT_TRUE(c.until([&] { return c.bodies.count(box) == 0; }));

  // reset: a new join (next epoch) with the scene's bodies and step.
  ASSERT_TRUE(c.answer(c.command(p::Type::spawn, spawn_box(6, 0, 1))));
  ASSERT_TRUE(c.answer(c.control(p::Type::reset)));
  ASSERT_TRUE(c.until([&] { return c.joins == 2; }));
  EXPECT_EQ(c.join.head.epoch, 1u);
  EXPECT_EQ(c.join.bodies.size(), scene_bodies);
  EXPECT_LT(c.join.head.step, 10u);
  EXPECT_EQ(c.last_problem, "");
}

TEST(Server, BadCommandsAreRefusedNamingTheFieldAndChangeNothing) {
  ServeProcess s = serve({"pile65"});
  ServerClient c(s.port(), "pile65", s.token());
  ASSERT_TRUE(c.until([&] { return c.joins == 1; }));
  ASSERT_TRUE(c.answer(c.control(p::Type::pause)));
  std::this_thread::sleep_for(100ms);
  const json before = world_metrics(s, "pile65");

  auto refused = [&](auto message, p::Type type) {
    const uint32_t seq = c.command(type, message);
    EXPECT_FALSE(c.answer(seq));
    return c.errors[seq];
  };
  p::Spawn bad = spawn_box(0, 0, 3);
  bad.orientation[0] = 0.5f;
  auto e = refused(bad, p::Type::spawn);
  EXPECT_EQ(e.field, "spawn.orientation");
  EXPECT_NE(e.reason.find("unit quaternion"), std::string::npos) << e.reason;
  EXPECT_EQ(e.head.code, uint16_t(p::ErrorCode::invalid));
  bad = spawn_box(0, std::nanf(""), 3);
  EXPECT_EQ(refused(bad, p::Type::spawn).field, "spawn.position[1]");
  bad = spawn_box(0, 0, 3);
  bad.shape = 99;
  EXPECT_EQ(refused(bad, p::Type::spawn).field, "spawn.shape");
  bad.shape = 0;  // the ground plane
  EXPECT_NE(refused(bad, p::Type::spawn).reason.find("plane"), std::string::npos);
  bad = spawn_box(0, 0, 3);
  bad.mass = -1;
  EXPECT_EQ(refused(bad, p::Type::spawn).field, "spawn.mass");
  p::Impulse im{};
  im.body = 5000;
  EXPECT_EQ(refused(im, p::Type::impulse).field, "impulse.body");
  im.body = 0;  // the ground: static
  EXPECT_NE(refused(im, p::Type::impulse).reason.find("static"), std::string::npos);
  im.body = 5;
  im.impulse[2] = 1e6f;
  EXPECT_EQ(refused(im, p::Type::impulse).field, "impulse.impulse");
  p::Remove rm{};
  rm.body = 4000;
  EXPECT_EQ(refused(rm, p::Type::remove).field, "remove.body");
  p::DragStart ds{};
  ds.body = 5;
  ds.target[0] = 1e9f;  // outside the region
  EXPECT_EQ(refused(ds, p::Type::drag_start).field, "drag_start.target[0]");
  // A message of the wrong size, and a wrong version, are refused by the header.
  p::Spawn sp = spawn_box(0, 0, 3);
  sp.header = {sizeof(p::Spawn), uint16_t(p::Type::spawn), p::kVersion};
  c.ws().send(&sp, sizeof sp - 4);
  ASSERT_TRUE(c.until([&] { return c.errors.count(0) > 0; }));
  EXPECT_EQ(c.errors[0].field, "header.length");
  c.errors.clear();
  sp.header.version = 7;
  c.ws().send(sp);
  ASSERT_TRUE(c.until([&] { return c.errors.count(0) > 0; }));
  EXPECT_EQ(c.errors[0].field, "header.version");

  std::this_thread::sleep_for(100ms);
  const json after = world_metrics(s, "pile65");
  EXPECT_EQ(after["state_hash"], before["state_hash"]);
  EXPECT_EQ(after["step"], before["step"]);
  EXPECT_EQ(after["bodies"], before["bodies"]);
  EXPECT_GE(after["commands_refused"].get<int>(), 12);
}

TEST(Server, CommandsNeedTheToken) {
  ServeProcess s = serve({"pile65"});
  for (const std::string& token : {std::string(), std::string("not-the-token")}) {
    ServerClient c(s.port(), "pile65", token);
    ASSERT_TRUE(c.until([&] { return c.joins == 1; }));  // watching needs none
    const uint32_t seq = c.command(p::Type::spawn, spawn_box(6, 0, 1));
    ASSERT_FALSE(c.answer(seq));
    EXPECT_EQ(c.errors[seq].head.code, uint16_t(p::ErrorCode::unauthorized));
    EXPECT_EQ(c.errors[seq].field, "token");
  }
  EXPECT_EQ(world_metrics(s, "pile65")["commands_accepted"], 0);
}

TEST(Server, FloodedCommandsAreRateLimitedThenTheConnectionClosed) {
  ServeProcess s = serve({"pile65", "--rate", "5", "--burst", "5"});
  ServerClient c(s.port(), "pile65", s.token());
  ASSERT_TRUE(c.until([&] { return c.joins == 1; }));
  std::vector<uint32_t> seqs;
  for (int i = 0; i < 20; ++i) seqs.push_back(c.control(p::Type::pause));
  int acked = 0, limited = 0;
  for (uint32_t q : seqs) {
    if (c.answer(q)) ++acked;
    else if (c.errors[q].head.code == uint16_t(p::ErrorCode::rate_limited) && c.errors[q].field == "rate") ++limited;
  }
  EXPECT_EQ(acked, 5);  // the burst
  EXPECT_EQ(limited, 15);
  // The connection stays up, and the bucket refills at 5 a second.
  std::this_thread::sleep_for(1200ms);
  EXPECT_TRUE(c.answer(c.control(p::Type::resume)));
  // Past ten bursts refused in a row, the server closes the connection.
  for (int i = 0; i < 80 && !c.ws().closed(); ++i) c.control(p::Type::pause);
  EXPECT_TRUE(c.until([&] { return c.ws().closed(); }, 5s));
  EXPECT_FALSE(c.ws().timed_out());
}

TEST(Server, AWorldThatFailsOrIsLoadedDoesNotStallAnother) {
  ServeProcess s = serve({"fails=pile65", "loaded=pile65", "healthy=pile65", "--fault", "fails=throw@30", "--fault",
                          "loaded=slow@40"});
  ServerClient c(s.port(), "fails", s.token());
  ASSERT_TRUE(c.until([&] {
    return !c.statuses.empty() && c.statuses.back().head.state == uint32_t(p::WorldState::failed);
  }));
  EXPECT_NE(c.statuses.back().text.find("test fault"), std::string::npos);
  std::this_thread::sleep_for(2500ms);
  const json fails = world_metrics(s, "fails"), loaded = world_metrics(s, "loaded"), healthy = world_metrics(s, "healthy");
  EXPECT_EQ(fails["state"], "failed");
  EXPECT_NE(fails["error"].get<std::string>().find("test fault"), std::string::npos);
  EXPECT_EQ(fails["step"], 29);
  EXPECT_LT(loaded["tick_hz"].get<double>(), 26.0);  // 40 ms a tick
  EXPECT_GT(loaded["late_ticks"].get<int>(), 0);
  EXPECT_GT(healthy["tick_hz"].get<double>(), 55.0);
  EXPECT_EQ(healthy["state"], "running");
  EXPECT_GT(healthy["step"].get<int>(), 150);
  // The failed world takes only reset, which brings it back.
  const uint32_t seq = c.command(p::Type::spawn, spawn_box(6, 0, 1));
  ASSERT_FALSE(c.answer(seq));
  EXPECT_EQ(c.errors[seq].head.code, uint16_t(p::ErrorCode::world_failed));
  ASSERT_TRUE(c.answer(c.control(p::Type::reset)));
  std::this_thread::sleep_for(500ms);
  EXPECT_EQ(world_metrics(s, "fails")["state"], "running");
  EXPECT_GT(world_metrics(s, "fails")["step"].get<int>(), 10);
}

TEST(Server, AClientThatStopsReadingIsDroppedAndTheTickHolds) {
  ServeProcess s = serve({"world1000", "--client-deadline", "1"});
  ServerClient reader(s.port(), "world1000");
  cellphys::test::WsClient stuck(s.port(), "/ws?world=world1000", 4096);  // never reads
  ASSERT_TRUE(reader.until([&] { return reader.joins == 1; }));
  reader.ticks.clear();
  const auto t0 = std::chrono::steady_clock::now();
  ASSERT_TRUE(reader.until([&] { return world_metrics(s, "world1000")["clients_dropped"].get<int>() >= 1; }, 15s));
  const double waited = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const json m = world_metrics(s, "world1000");
  EXPECT_EQ(m["clients"], 1);
#ifndef CELLPHYS_SANITIZED  // under the sanitizers world1000 steps slower than 60 Hz by itself
  // The reader got the ticks of that time at the full rate while the other client was stuck.
  EXPECT_GE(double(reader.ticks.size()), 50.0 * waited) << waited << " s";
  EXPECT_GT(m["tick_hz"].get<double>(), 55.0);
#endif
}

// `cellphys ARGS` (a shell command line): its exit code, and its standard output and error in `out`.
int run_cellphys(const std::string& args, std::string& out) {
  const std::string cmd = "'" + kExe + "' " + args + " 2>&1";
  FILE* pipe = popen(cmd.c_str(), "r");
  char buf[4096];
  while (size_t n = fread(buf, 1, sizeof buf, pipe)) out.append(buf, n);
  const int st = pclose(pipe);
  return WIFEXITED(st) ? WEXITSTATUS(st) : -1;
}

// `cellphys replay FILE [args]`.
int replay(const fs::path& file, std::string& out, const std::string& args = "") {
  return run_cellphys("replay '" + file.string() + "' " + args, out);
}

// A recording's records (server/recording.h), to read and rewrite files as other versions or
// damaged ones would be.
struct RecordFile {
  struct Record {
    uint32_t type;
    std::vector<unsigned char> payload;
  };
  uint32_t version = 0, flags = 0;
  std::vector<Record> records;

  static RecordFile read(const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    const std::vector<unsigned char> b((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    RecordFile f;
    std::memcpy(&f.version, b.data() + 8, 4);
    std::memcpy(&f.flags, b.data() + 12, 4);
    for (size_t at = 16; at + 16 <= b.size();) {
      uint32_t h[4];
      std::memcpy(h, b.data() + at, 16);
      if (at + 16 + h[1] > b.size()) break;
      f.records.push_back({h[0], std::vector<unsigned char>(b.begin() + at + 16, b.begin() + at + 16 + h[1])});
      at += 16 + h[1];
    }
    return f;
  }
  void write(const fs::path& path) const {
    std::ofstream o(path, std::ios::binary);
    o.write("CELLREC1", 8);
    o.write(reinterpret_cast<const char*>(&version), 4);
    o.write(reinterpret_cast<const char*>(&flags), 4);
    for (const Record& r : records) {
      uint32_t h[4] = {r.type, static_cast<uint32_t>(r.payload.size()), 0, 0};
      // The record's checksum, as the writer makes it: its header with this field zero, then the payload.
      h[2] = cellphys::spu::checksum(r.payload.data(), r.payload.size(),
                                     cellphys::spu::checksum(reinterpret_cast<const unsigned char*>(h), 16));
      o.write(reinterpret_cast<const char*>(h), 16);
      o.write(reinterpret_cast<const char*>(r.payload.data()), static_cast<std::streamsize>(r.payload.size()));
    }
  }
  size_t count(uint32_t type) const {
    return static_cast<size_t>(std::count_if(records.begin(), records.end(), [&](const Record& r) { return r.type == type; }));
  }
  // Frame records holding a message of this type.
  size_t count_messages(p::Type type) const {
    size_t n = 0;
    for (const Record& r : records)
      n += r.type == 5 && cellphys::server::message_type(r.payload.data() + 8, r.payload.size() - 8) == uint16_t(type);
    return n;
  }
};

TEST(Server, ARecordingReplaysToTheLiveStateHash) {
  const fs::path dir = fs::temp_directory_path() / ("cellphys_server_" + std::to_string(getpid()));
  fs::create_directories(dir);
  const fs::path rec = dir / "pile65.rec";
  std::string live_hash;
  uint64_t live_step = 0;
  {
    ServeProcess s = serve({"pile65", "--record", rec.string()});
    ServerClient c(s.port(), "pile65", s.token());
    ASSERT_TRUE(c.until([&] { return c.joins == 1 && c.ticks.size() > 5; }));
    const uint32_t sp = c.command(p::Type::spawn, spawn_box(6, 0, 1));
    ASSERT_TRUE(c.answer(sp));
    p::Impulse im{};
    im.body = 10;
    im.impulse[2] = 4;
    std::copy(c.bodies[10].position, c.bodies[10].position + 3, im.point);
    ASSERT_TRUE(c.answer(c.command(p::Type::impulse, im)));
    p::DragStart ds{};
    ds.body = c.acks[sp].result;
    ds.point[0] = 6;
    ds.point[2] = 1;
    ds.target[0] = 6;
    ds.target[2] = 2;
    const uint32_t dq = c.command(p::Type::drag_start, ds);
    ASSERT_TRUE(c.answer(dq));
    c.ticks.clear();
    ASSERT_TRUE(c.until([&] { return c.ticks.size() > 10; }));
    p::DragRelease dr{};
    dr.drag = c.acks[dq].result;
    ASSERT_TRUE(c.answer(c.command(p::Type::drag_release, dr)));
    ASSERT_TRUE(c.answer(c.control(p::Type::reset)));
    ASSERT_TRUE(c.until([&] { return c.joins == 2; }));
    c.ticks.clear();
    ASSERT_TRUE(c.until([&] { return c.ticks.size() > 10; }));
    ASSERT_TRUE(c.answer(c.command(p::Type::spawn, spawn_box(-6, 0, 2))));
    ASSERT_TRUE(c.answer(c.control(p::Type::pause)));
    std::this_thread::sleep_for(100ms);
    const json m = world_metrics(s, "pile65");
    live_hash = m["state_hash"];
    live_step = m["step"];
    EXPECT_EQ(s.stop(SIGTERM), 0);
  }
  std::string out;
  EXPECT_EQ(replay(rec, out), 0) << out;
  EXPECT_NE(out.find("state hash " + live_hash), std::string::npos) << out << " live " << live_hash;
  EXPECT_NE(out.find("step " + std::to_string(live_step) + "\n"), std::string::npos) << out;
  EXPECT_NE(out.find(" 7 commands"), std::string::npos) << out;
  // Every frame the server recorded (two joins: the start and the reset) made again, byte for byte.
  const RecordFile file = RecordFile::read(rec);
  const size_t frames = file.count_messages(p::Type::join) + file.count_messages(p::Type::tick);
  EXPECT_NE(out.find(" " + std::to_string(frames) + " frames and " + std::to_string(frames) + " stages matched"),
            std::string::npos) << out;
  EXPECT_EQ(file.count_messages(p::Type::stages), frames);
  EXPECT_GT(frames, 30u);
  EXPECT_EQ(file.count_messages(p::Type::join), 2u);

  // A server killed outright leaves a recording that still replays, up to its last whole record.
  const fs::path killed = dir / "killed.rec";
  {
    ServeProcess s = serve({"pile65", "--record", killed.string()});
    ServerClient c(s.port(), "pile65", s.token());
    ASSERT_TRUE(c.until([&] { return c.ticks.size() > 5; }));
    ASSERT_TRUE(c.answer(c.command(p::Type::spawn, spawn_box(6, 0, 1))));
    ASSERT_TRUE(c.until([&] { return c.ticks.size() > 20; }));
    s.stop(SIGKILL);
  }
  out.clear();
  EXPECT_EQ(replay(killed, out), 0) << out;
  EXPECT_NE(out.find("stages matched"), std::string::npos) << out;
  // (killed between records, or in the middle of one)
  EXPECT_TRUE(out.find("no end record") != std::string::npos || out.find("cut short") != std::string::npos) << out;
  EXPECT_NE(out.find("1 commands"), std::string::npos) << out;
  // A damaged record stops the replay there, with a warning, and what comes before it matches.
  const auto size = fs::file_size(killed);
  {
    FILE* f = std::fopen(killed.c_str(), "r+b");
    std::fseek(f, static_cast<long>(size - 200), SEEK_SET);  // among the last steps' hash records
    std::fputc(0x5A, f);
    std::fclose(f);
  }
  out.clear();
  EXPECT_EQ(replay(killed, out), 0) << out;
  EXPECT_NE(out.find("damaged"), std::string::npos) << out;
  fs::remove_all(dir);
}

// Recording format 2 (frames), --record-frames off, version 1 files, unknown versions, files that
// are no recording, and replay's frame check catching a frame that differs where no hash does.
TEST(Server, RecordingFormatsAndTheFrameCheck) {
  const fs::path dir = fs::temp_directory_path() / ("cellphys_recfmt_" + std::to_string(getpid()));
  fs::create_directories(dir);
  const fs::path with = dir / "frames.rec", without = dir / "noframes.rec";
  for (const fs::path& rec : {with, without}) {
    std::vector<std::string> args = {"pile65", "--record", rec.string()};
    if (rec == without) args.insert(args.end(), {"--record-frames", "off"});
    ServeProcess s = serve(args);
    ServerClient c(s.port(), "pile65", s.token());
    ASSERT_TRUE(c.until([&] { return c.ticks.size() > 5; }));
    ASSERT_TRUE(c.answer(c.command(p::Type::spawn, spawn_box(6, 0, 1))));
    ASSERT_TRUE(c.until([&] { return c.ticks.size() > 40; }));
    EXPECT_EQ(s.stop(SIGTERM), 0);
  }
  const RecordFile f2 = RecordFile::read(with), off = RecordFile::read(without);
  EXPECT_EQ(f2.version, 2u);
  EXPECT_EQ(f2.flags, 1u);
  EXPECT_EQ(f2.count_messages(p::Type::join), 1u);
  EXPECT_GT(f2.count_messages(p::Type::tick), 40u);
  EXPECT_EQ(off.flags, 0u);
  EXPECT_EQ(off.count(5), 0u);
  EXPECT_EQ(off.count(2), 1u);
  EXPECT_LT(fs::file_size(without), fs::file_size(with));

  std::string out;
  EXPECT_EQ(replay(with, out), 0) << out;
  EXPECT_NE(out.find(" " + std::to_string(f2.count(5) / 2) + " frames and "), std::string::npos) << out;
  const std::string hash_line = out.substr(out.find("state hash "));
  out.clear();
  EXPECT_EQ(replay(without, out), 0) << out;
  EXPECT_NE(out.find("no frames (recorded with --record-frames off)"), std::string::npos) << out;

  // Version 1, as the previous format wrote it: the same records without frames, flags 0.
  RecordFile v1 = f2;
  v1.version = 1;
  v1.flags = 0;
  v1.records.erase(std::remove_if(v1.records.begin(), v1.records.end(), [](const RecordFile::Record& r) { return r.type == 5; }),
                   v1.records.end());
  v1.write(dir / "v1.rec");
  out.clear();
  EXPECT_EQ(replay(dir / "v1.rec", out), 0) << out;
  EXPECT_NE(out.find("no frames (a version-1 recording)"), std::string::npos) << out;
  EXPECT_NE(out.find(hash_line), std::string::npos) << out << " wanted " << hash_line;

  // A version this cellphys does not know, and a file that is no recording: refused, naming the file.
  RecordFile v3 = f2;
  v3.version = 3;
  v3.write(dir / "v3.rec");
  out.clear();
  EXPECT_EQ(replay(dir / "v3.rec", out), 2) << out;
  EXPECT_NE(out.find((dir / "v3.rec").string() + ": recording version 3 is not one this cellphys reads (1 to 2)"),
            std::string::npos) << out;
  out.clear();
  EXPECT_EQ(replay(kScenes + "/pile65.json", out), 2) << out;
  EXPECT_NE(out.find("pile65.json: not a cellphys recording"), std::string::npos) << out;
  out.clear();
  EXPECT_EQ(replay(dir / "missing.rec", out), 2) << out;
  EXPECT_NE(out.find("missing.rec: cannot open the recording"), std::string::npos) << out;

  // A recording made before revision 4 (its joins announce 3) of a world with no mesh, height
  // field or compound replays: its join is the same bytes as revision 3 would send.
  RecordFile older = f2;
  int joins = 0;
  for (auto& r : older.records)
    if (r.type == 5 && cellphys::server::message_type(r.payload.data() + 8, r.payload.size() - 8) == uint16_t(p::Type::join)) {
      const uint32_t three = 3;
      std::memcpy(r.payload.data() + 8 + offsetof(p::Join, revision), &three, 4);
      ++joins;
    }
  ASSERT_GT(joins, 0);
  older.write(dir / "revision3.rec");
  out.clear();
  EXPECT_EQ(replay(dir / "revision3.rec", out), 0) << out;
  EXPECT_NE(out.find("stages matched"), std::string::npos) << out;

  // One float of one moved body changed in a recorded tick (its checksum made good): no state
  // hash notices, the frame check does, and names the body.
  RecordFile bad = f2;
  size_t k = 0;
  int ticks_seen = 0;
  for (; k < bad.records.size(); ++k) {
    const auto& r = bad.records[k];
    if (r.type != 5 || cellphys::server::message_type(r.payload.data() + 8, r.payload.size() - 8) != uint16_t(p::Type::tick)) continue;
    p::Tick t;
    std::memcpy(&t, r.payload.data() + 8, sizeof t);
    if (t.num_moved > 0 && t.num_entered == 0 && ++ticks_seen == 10) break;
  }
  ASSERT_LT(k, bad.records.size());
  uint64_t bad_step;
  std::memcpy(&bad_step, bad.records[k].payload.data(), 8);
  p::BodyMoved moved;
  std::memcpy(&moved, bad.records[k].payload.data() + 8 + sizeof(p::Tick), sizeof moved);
  moved.position[2] += 0.25f;
  std::memcpy(bad.records[k].payload.data() + 8 + sizeof(p::Tick), &moved, sizeof moved);
  bad.write(dir / "bad.rec");
  out.clear();
  EXPECT_EQ(replay(dir / "bad.rec", out), 1) << out;
  EXPECT_NE(out.find("the frame at step " + std::to_string(bad_step) + " differs from the recorded one"), std::string::npos) << out;
  EXPECT_NE(out.find("moved record 0, body " + std::to_string(moved.id) + ")"), std::string::npos) << out;
  // A stages message naming a stage this build does not have (one letter of its first name changed).
  RecordFile renamed = f2;
  for (auto& r : renamed.records)
    if (r.type == 5 && cellphys::server::message_type(r.payload.data() + 8, r.payload.size() - 8) == uint16_t(p::Type::stages)) {
      const size_t names = 8 + sizeof(p::Stages) + 4 * std::size(cellphys::ppe::kStageTimeFields);
      r.payload[names] ^= 0x20;  // "broad" -> "Broad"
      break;
    }
  renamed.write(dir / "renamed.rec");
  out.clear();
  EXPECT_EQ(replay(dir / "renamed.rec", out), 1) << out;
  EXPECT_NE(out.find("differs from the recorded one: stages of"), std::string::npos) << out;
  fs::remove_all(dir);
}

// `--record-debug on`: every recorded frame keeps its debug message (header flag 2), which
// replay makes again byte for byte; a changed contact force is caught and named. The option
// needs the frames it goes with.
TEST(Server, RecordingKeepsTheDebugMessagesReplayMakesAgain) {
  const fs::path dir = fs::temp_directory_path() / ("cellphys_recdebug_" + std::to_string(getpid()));
  fs::create_directories(dir);
  const fs::path rec = dir / "debug.rec";
  {
    ServeProcess s = serve({"pile65", "--record", rec.string(), "--record-debug", "on"});
    ServerClient c(s.port(), "pile65", s.token());
    ASSERT_TRUE(c.until([&] { return c.ticks.size() > 5; }));
    ASSERT_TRUE(c.answer(c.command(p::Type::spawn, spawn_box(6, 0, 3))));  // a landing in the recording
    ASSERT_TRUE(c.until([&] { return c.ticks.size() > 60; }));
    EXPECT_EQ(s.stop(SIGTERM), 0);
  }
  const RecordFile f = RecordFile::read(rec);
  EXPECT_EQ(f.flags, 3u);
  const size_t frames = f.count_messages(p::Type::join) + f.count_messages(p::Type::tick);
  EXPECT_GT(frames, 60u);
  EXPECT_EQ(f.count_messages(p::Type::debug), frames);
  std::string out;
  EXPECT_EQ(replay(rec, out), 0) << out;
  EXPECT_NE(out.find(" " + std::to_string(frames) + " frames and " + std::to_string(frames) + " stages and " +
                     std::to_string(frames) + " debug messages matched"),
            std::string::npos) << out;

  // One contact's force changed in a recorded debug message (its checksum made good).
  RecordFile bad = f;
  uint64_t bad_step = 0;
  for (auto& r : bad.records) {
    if (r.type != 5 || cellphys::server::message_type(r.payload.data() + 8, r.payload.size() - 8) != uint16_t(p::Type::debug)) continue;
    p::Debug d;
    std::memcpy(&d, r.payload.data() + 8, sizeof d);
    if (d.num_contacts == 0) continue;
    const size_t at = 8 + sizeof d + d.num_bodies * sizeof(p::DebugBody) + offsetof(p::DebugContact, force);
    float force;
    std::memcpy(&force, r.payload.data() + at, 4);
    force += 1.0f;
    std::memcpy(r.payload.data() + at, &force, 4);
    std::memcpy(&bad_step, r.payload.data(), 8);
    break;
  }
  ASSERT_GT(bad_step, 0u);
  bad.write(dir / "bad.rec");
  out.clear();
  EXPECT_EQ(replay(dir / "bad.rec", out), 1) << out;
  EXPECT_NE(out.find("the frame at step " + std::to_string(bad_step) + " differs from the recorded one: debug of"),
            std::string::npos) << out;

  out.clear();
  EXPECT_EQ(run_cellphys("serve pile65 --port 0 --record '" + (dir / "x.rec").string() +
                             "' --record-frames off --record-debug on",
                         out),
            2)
      << out;
  EXPECT_NE(out.find("--record-debug on keeps a debug message with each recorded frame: it needs --record-frames on"),
            std::string::npos) << out;
  EXPECT_FALSE(fs::exists(dir / "x.rec"));
  fs::remove_all(dir);
}

// set_speed (revision 5): the room steps at that pace against real time, each step of the
// world's dt; a speed out of range, or not a number, is refused by field.
TEST(Server, SetSpeedPacesTheTicks) {
  ServeProcess s = serve({"pile65"});
  ServerClient c(s.port(), "pile65", s.token());
  ASSERT_TRUE(c.until([&] { return c.ticks.size() > 5; }));
  EXPECT_EQ(c.join.head.revision, 5u);
  auto speed = [&](float v) {
    p::SetSpeed m{};
    m.speed = v;
    return c.command(p::Type::set_speed, m);
  };
  for (float bad : {0.0f, -1.0f, 9.0f, std::nanf("")}) {
    const uint32_t q = speed(bad);
    ASSERT_TRUE(c.until([&] { return c.errors.count(q) > 0; }));
    EXPECT_EQ(c.errors[q].field, "set_speed.speed") << bad;
    EXPECT_NE(c.errors[q].reason.find("is not from 0.05 to 8 (times real time)"), std::string::npos) << c.errors[q].reason;
  }
  ASSERT_TRUE(c.answer(speed(0.5f)));
  std::this_thread::sleep_for(2500ms);  // the metrics' rate is over the last 2 s
  json m = world_metrics(s, "pile65");
  EXPECT_EQ(m["speed"].get<double>(), 0.5);
  EXPECT_EQ(m["tick_hz_target"].get<double>(), 30.0);
  EXPECT_GT(m["tick_hz"].get<double>(), 20.0);
  EXPECT_LT(m["tick_hz"].get<double>(), 36.0);
  ASSERT_TRUE(c.answer(speed(2.0f)));
  std::this_thread::sleep_for(2500ms);
  m = world_metrics(s, "pile65");
  EXPECT_EQ(m["tick_hz_target"].get<double>(), 120.0);
#ifndef CELLPHYS_SANITIZED  // under the sanitizers a step may take longer than 8 ms
  EXPECT_GT(m["tick_hz"].get<double>(), 80.0);
#endif
}

TEST(Server, MetricsAreJsonWithEveryField) {
  // A viewer directory that does not exist: `/` is then the page listing the worlds (the built
  // viewer, viewer/dist, is tested in the browser by viewer/test).
  ServeProcess s = serve({"pile65", "b=stack10", "--viewer", "/nonexistent/cellphys-viewer"});
  ServerClient c(s.port(), "b");
  ASSERT_TRUE(c.until([&] { return c.ticks.size() > 30; }));
  const json m = metrics(s);
  ASSERT_EQ(m["worlds"].size(), 2u);
  for (const json& w : m["worlds"]) {
    for (const char* f : {"name", "source", "state", "error", "state_hash", "recording"})
      EXPECT_TRUE(w[f].is_string()) << f;
    for (const char* f : {"step", "tick_hz", "tick_hz_target", "speed", "step_ms_median", "step_ms_p99", "bodies", "bodies_awake",
                          "bodies_asleep", "clients", "bytes_sent", "bytes_sent_per_s", "commands_accepted",
                          "commands_refused", "frames_skipped", "clients_dropped", "late_ticks", "failed_islands"})
      EXPECT_TRUE(w[f].is_number()) << f;
    EXPECT_TRUE(w["stage_ms_mean"]["integrate"].is_number());
    EXPECT_EQ(w["bodies"].get<int>(), w["bodies_awake"].get<int>() + w["bodies_asleep"].get<int>());
  }
  const json& b = m["worlds"][1];
  EXPECT_EQ(b["name"], "b");
  EXPECT_EQ(b["clients"], 1);
  EXPECT_GT(b["bytes_sent"].get<double>(), 0);
  EXPECT_GT(b["step_ms_p99"].get<double>(), 0);
  EXPECT_GE(b["step_ms_p99"].get<double>(), b["step_ms_median"].get<double>());
  // Per client: its bytes and their rate over the last second; a tick is at least 96 bytes, at 60 Hz.
  ASSERT_TRUE(c.until([&] { return c.ticks.size() > 150; }));
  const json later = metrics(s)["worlds"][1];
  ASSERT_EQ(later["per_client"].size(), 1u);
  const json& me = later["per_client"][0];
  EXPECT_GT(me["bytes_sent"].get<double>(), 0);
  EXPECT_LE(me["bytes_sent"].get<double>(), later["bytes_sent"].get<double>());
  EXPECT_GE(me["bytes_sent_per_s"].get<double>(), 0.5 * 60 * 96);
  EXPECT_TRUE(m["worlds"][0]["per_client"].empty());
  const auto [status, page] = cellphys::test::http_get(s.port(), "/");
  EXPECT_EQ(status, 200);
  EXPECT_NE(page.find("/ws?world=pile65"), std::string::npos);
  EXPECT_EQ(cellphys::test::http_get(s.port(), "/nothing/here").first, 404);
}

// In process: the debug message of the reference pile in a 32 KiB local store (its island needs
// 126 kB; kept awake, it settles into islands of which one or two are cut in parts every step),
// carries every coupling the step cut, each between two bodies of the decoupled island it names,
// at one of the step's contacts.
TEST(DebugMessage, CarriesEveryCouplingDecouplingCut) {
  cellphys::scene::SceneDesc desc = cellphys::scene::load_scene(kScenes + "/pile65.json");
  desc.settings.local_store_bytes = 32 * 1024;
  desc.settings.whole_island_bytes = 0;  // split, not computed whole
  desc.settings.sleeping = false;
  auto scene = cellphys::scene::build_world(desc);
  cellphys::ppe::World& w = *scene.world;
  uint32_t most = 0;
  for (int i = 0; i < 60; ++i) {
    const cellphys::ppe::StepStats& st = w.step();
    const std::vector<unsigned char> bytes = cellphys::server::encode_debug(w, 0);
    cellphys::server::DebugMessage d;
    ASSERT_EQ(cellphys::server::decode_debug(bytes.data(), bytes.size(), d), "") << "step " << st.step;
    ASSERT_EQ(d.cuts.size(), st.cut_couplings) << "step " << st.step;
    ASSERT_EQ(w.cut_couplings().size(), st.cut_couplings);
    most = std::max(most, st.cut_couplings);
    std::map<uint32_t, p::DebugBody> bodies;
    for (const p::DebugBody& b : d.bodies) bodies[b.id] = b;
    for (const p::DebugCut& c : d.cuts) {
      ASSERT_TRUE(bodies.count(c.a) && bodies.count(c.b)) << c.a << "-" << c.b;
      EXPECT_EQ(bodies[c.a].island, c.island);
      EXPECT_EQ(bodies[c.b].island, c.island);
      EXPECT_TRUE(bodies[c.a].flags & p::kIslandDecoupled);
      EXPECT_EQ(c.force, p::kNoForce);  // the pile has no forces between bodies: contacts only
      const bool at_a_contact = std::any_of(d.contacts.begin(), d.contacts.end(), [&](const p::DebugContact& k) {
        return ((k.a == c.a && k.b == c.b) || (k.a == c.b && k.b == c.a)) && std::memcmp(k.point, c.point, 12) == 0;
      });
      EXPECT_TRUE(at_a_contact) << "cut " << c.a << "-" << c.b << " at step " << st.step;
    }
  }
  EXPECT_GT(most, 0u) << "the pile was never cut";
}

// The debug message's contact forces are what the step applied: over a step, a body's contact
// forces on the ground times the step are the momentum they gave it (its change of velocity
// against free fall's), landing or at rest. Spheres and boxes of several sizes and masses,
// dropped from several heights, each on its own patch of ground. A step in which a contact sits
// at the hold depth is left out: the push stage leaves a deep landing there, and whether the
// kernel's spring is flat at that depth (deeper than the hold depth) turns on the rounding of
// its float depth, which the world cannot see after the step.
TEST(DebugMessage, ContactForcesAreTheMomentumTheStepGave) {
  using namespace cellphys::ppe;
  WorldSettings settings;
  settings.sleeping = false;  // a body falling asleep has its speed zeroed by the sleep stage, not a force
  World w(settings);
  const float up[3] = {0, 0, 1};
  BodyDesc ground;
  ground.shape = w.shapes().add_plane(up, 0.0f);
  ground.is_static = true;
  w.add_body(ground);
  struct Drop {
    bool sphere;
    float size, mass, height;  // radius or half side (m), kg, lowest point above the ground (m)
  };
  const Drop drops[] = {{true, 0.15f, 0.4f, 0.3f}, {false, 0.25f, 5.0f, 0.8f}, {false, 0.6f, 800.0f, 0.4f},
                        {true, 0.5f, 60.0f, 1.5f}, {false, 0.1f, 0.05f, 0.05f}, {false, 0.4f, 50.0f, 1.2f}};
  std::vector<BodyId> ids;
  for (size_t i = 0; i < std::size(drops); ++i) {
    const Drop& c = drops[i];
    const float half[3] = {c.size, c.size, c.size};
    BodyDesc d;
    d.shape = c.sphere ? w.shapes().add_sphere(c.size) : w.shapes().add_box(half);
    d.mass = c.mass;
    d.state.position[0] = 3.0f * float(i);
    d.state.position[2] = c.size + c.height;
    ids.push_back(w.add_body(d));
  }
  const double h = w.settings().dt, g = -w.settings().globals.gravity[2];
  std::vector<int> landings(ids.size(), 0);
  for (int step = 0; step < 150; ++step) {
    std::vector<float> before;
    for (BodyId id : ids) before.push_back(w.state(id).velocity[2]);
    w.step();
    cellphys::server::DebugMessage d;
    const std::vector<unsigned char> bytes = cellphys::server::encode_debug(w, 0);
    ASSERT_EQ(cellphys::server::decode_debug(bytes.data(), bytes.size(), d), "");
    const float hold = w.settings().globals.contact_hold_depth;
    for (size_t i = 0; i < ids.size(); ++i) {
      double impulse = 0;  // up, from the ground's contacts (the normal points from the body to the ground)
      bool at_hold = false;
      for (const p::DebugContact& k : d.contacts)
        if (k.a == ids[i]) {
          impulse += h * k.force * -k.normal[2];
          at_hold = at_hold || std::fabs(k.depth - hold) < 1e-7f;
        }
      if (at_hold) continue;
      const double m = drops[i].mass, gained = m * (double(w.state(ids[i]).velocity[2]) - before[i] + g * h);
      SCOPED_TRACE("body " + std::to_string(i) + " step " + std::to_string(step));
      EXPECT_NEAR(impulse, gained, 0.02 * std::fabs(gained) + 1e-3 * m * g * h);
      if (gained > 3 * m * g * h) ++landings[i];
    }
  }
  cellphys::server::DebugMessage rest;
  const std::vector<unsigned char> bytes = cellphys::server::encode_debug(w, 0);
  ASSERT_EQ(cellphys::server::decode_debug(bytes.data(), bytes.size(), rest), "");
  for (size_t i = 0; i < ids.size(); ++i) {
    EXPECT_GE(landings[i], 1) << "body " << i << " never landed hard";
    double up_force = 0;  // at rest: the weight
    for (const p::DebugContact& k : rest.contacts)
      if (k.a == ids[i]) up_force += k.force * -k.normal[2];
    EXPECT_NEAR(up_force, drops[i].mass * g, 0.01 * drops[i].mass * g) << "body " << i;
  }
}

// In process: the quantised state of world1000's moving bodies against full precision.
TEST(Quantisation, ErrorIsWithinHalfAStep) {
  auto scene = built("world1000");
  cellphys::ppe::World& w = *scene.world;
  for (int i = 0; i < 30; ++i) w.step();  // half the bodies falling
  cellphys::server::Frame f;
  f.seq = 2;
  for (cellphys::ppe::BodyId id : w.bodies()) {
    cellphys::server::FrameBody b;
    b.id = id;
    b.shape = w.shape(id);
    b.state = w.state(id);
    b.changed = 2;
    f.bodies.push_back(b);
  }
  std::vector<uint32_t> all;
  for (const auto& b : f.bodies) all.push_back(b.id);
  cellphys::server::Interest full, quant;
  quant.quantised = true;
  std::vector<unsigned char> fb, qb;
  std::vector<uint32_t> k1 = all, k2 = all;
  cellphys::server::encode_tick(f, full, 1, 0, k1, fb);
  cellphys::server::encode_tick(f, quant, 1, 0, k2, qb);
  cellphys::server::TickMessage ft, qt;
  ASSERT_EQ(cellphys::server::decode_tick(fb.data(), fb.size(), ft), "");
  ASSERT_EQ(cellphys::server::decode_tick(qb.data(), qb.size(), qt), "");
  ASSERT_EQ(ft.moved.size(), f.bodies.size());
  ASSERT_EQ(qt.moved.size(), f.bodies.size());
  const p::QuantFrame& q = qt.head.quant;
  double pos = 0, vel = 0, ang = 0, rot = 0;
  for (size_t i = 0; i < f.bodies.size(); ++i) {
    const auto& a = f.bodies[i].state;
    const auto& full_state = ft.moved[i].second;
    const auto& b = qt.moved[i].second;
    EXPECT_EQ(std::memcmp(&a, &full_state, sizeof a), 0);  // full precision is the world's bits
    for (int k = 0; k < 3; ++k) {
      pos = std::max(pos, double(std::fabs(a.position[k] - b.position[k])));
      vel = std::max(vel, double(std::fabs(a.velocity[k] - b.velocity[k])));
      ang = std::max(ang, double(std::fabs(a.angular_velocity[k] - b.angular_velocity[k])));
    }
    double dot = 0;
    for (int k = 0; k < 4; ++k) dot += double(a.orientation[k]) * b.orientation[k];
    rot = std::max(rot, 2.0 * std::acos(std::min(1.0, std::fabs(dot))));
  }
  std::printf("world1000 after 30 steps, %zu bodies: quantised %zu B, full %zu B; max error position %.3g m "
              "(step %.3g), velocity %.3g m/s (step %.3g), angular velocity %.3g rad/s (step %.3g), rotation %.3g rad\n",
              f.bodies.size(), qb.size(), fb.size(), pos, q.position_step, vel, q.velocity_step, ang, q.angular_step, rot);
  RecordProperty("position_error_m", std::to_string(pos));
  RecordProperty("rotation_error_rad", std::to_string(rot));
  // Half a step, and the float rounding of a value of the world's size (1e-5 relative at 100 m).
  EXPECT_LE(pos, 0.5 * q.position_step + 2e-5);
  EXPECT_LE(vel, 0.5 * q.velocity_step + 1e-6);
  EXPECT_LE(ang, 0.5 * q.angular_step + 1e-6);
  EXPECT_GT(q.velocity_step, 0);  // something moves
  // Three components at 10 bits over [-1/sqrt 2, 1/sqrt 2], half a level each (|dc| <= sqrt 3 half a
  // level); the largest, rebuilt from them, is off by at most sqrt 3 |dc| (it is >= 1/2), so
  // |dq| <= 2 |dc| and the angle 2 |dq|.
  const double half_level = std::sqrt(2.0) / 1023.0 / 2.0;
  EXPECT_LE(rot, 4.0 * std::sqrt(3.0) * half_level * 1.01);
  EXPECT_EQ(qb.size(), sizeof(p::Tick) + f.bodies.size() * sizeof(p::BodyMovedQ));
  EXPECT_EQ(fb.size(), sizeof(p::Tick) + f.bodies.size() * sizeof(p::BodyMoved));
}

TEST(Quantisation, OrientationRoundTripsAcrossEveryLargestComponent) {
  for (int largest = 0; largest < 4; ++largest)
    for (float sign : {1.0f, -1.0f}) {
      float q[4] = {0.1f, -0.2f, 0.3f, 0.0f};
      q[largest] = sign * 0.9f;
      const double n = std::sqrt(double(q[0]) * q[0] + double(q[1]) * q[1] + double(q[2]) * q[2] + double(q[3]) * q[3]);
      for (float& v : q) v = static_cast<float>(v / n);
      float back[4];
      cellphys::server::unpack_orientation(cellphys::server::pack_orientation(q), back);
      double dot = 0;
      for (int k = 0; k < 4; ++k) dot += double(q[k]) * back[k];
      EXPECT_GT(std::fabs(dot), 1.0 - 1e-5) << "largest " << largest << " sign " << sign;
    }
}

}  // namespace
