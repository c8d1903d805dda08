// Level geometry: static triangle meshes and height fields (docs/scene-format.md, "Meshes and
// height fields"). A flat surface of many triangles must give what a plane gives: bodies that
// land, rest, slide and roll on it as on the plane (the plane is the reference), nothing that
// snags on the edges between its triangles, one-sided triangles, convex creases and borders
// that still push sideways; then the hierarchy, the rays and sweeps against brute force, bad
// input refused by name, and scene files and snapshots that carry surfaces.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include "runtime/ppe/shape_ray.h"
#include "runtime/ppe/world.h"
#include "runtime/scene/scene.h"
#include "runtime/spu/narrow_phase.h"
#include "runtime/spu/surface_tree.h"

namespace {

using namespace cellphys::ppe;
namespace spu = cellphys::spu;
using cellphys::Vec3d;

constexpr double kPi = 3.14159265358979323846;

// A flat square grid of n x n cells of side `cell` at height z, centred on the origin, as a
// mesh (the same as a height field's triangles, but given as vertices and triangles).
void flat_grid(int n, float cell, float z, std::vector<float>& v, std::vector<int32_t>& t) {
  v.clear(), t.clear();
  for (int i = 0; i <= n; ++i)
    for (int j = 0; j <= n; ++j) v.insert(v.end(), {(j - 0.5f * n) * cell, (i - 0.5f * n) * cell, z});
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) {
      const int32_t a = i * (n + 1) + j, b = a + 1, d = a + n + 1, c = d + 1;
      t.insert(t.end(), {a, b, c, a, c, d});
    }
}

enum class Ground { plane, mesh, height_field };
const char* ground_name(Ground g) { return g == Ground::plane ? "plane" : g == Ground::mesh ? "mesh" : "height field"; }

// The ground as a plane at z = 0, a flat mesh of `cells` x `cells` triangles pairs of side
// `cell`, or a flat height field of the same grid, tilted by `tilt` radians about y.
BodyId add_ground(World& w, Ground g, int cells = 40, float cell = 0.5f, double tilt = 0.0) {
  BodyDesc d;
  d.is_static = true;
  d.friction = 0.5f;
  const float q[4] = {float(std::cos(tilt / 2)), 0.0f, float(std::sin(tilt / 2)), 0.0f};
  std::copy(q, q + 4, d.state.orientation);
  if (g == Ground::plane) {
    const float up[3] = {float(std::sin(tilt)), 0.0f, float(std::cos(tilt))};
    d.shape = w.shapes().add_plane(up, 0.0f);
    std::fill(d.state.orientation, d.state.orientation + 4, 0.0f);
    d.state.orientation[0] = 1.0f;
  } else if (g == Ground::mesh) {
    std::vector<float> v;
    std::vector<int32_t> t;
    flat_grid(cells, cell, 0.0f, v, t);
    d.shape = w.shapes().add_mesh(v.data(), int(v.size() / 3), t.data(), int(t.size() / 3));
  } else {
    std::vector<float> h(size_t(cells + 1) * (cells + 1), 0.0f);
    const float spacing[2] = {cell, cell};
    d.shape = w.shapes().add_height_field(cells + 1, cells + 1, spacing, h.data());
  }
  return w.add_body(d);
}

enum class Kind { sphere, box, capsule };
const char* kind_name(Kind k) { return k == Kind::sphere ? "sphere" : k == Kind::box ? "box" : "capsule"; }

BodyId add_thing(World& w, Kind k, float size, float mass, const float at[3], const float v[3] = nullptr,
                 float friction = 0.5f) {
  BodyDesc d;
  if (k == Kind::sphere) d.shape = w.shapes().add_sphere(size);
  if (k == Kind::box) {
    const float h[3] = {size, 0.7f * size, 0.5f * size};
    d.shape = w.shapes().add_box(h);
  }
  if (k == Kind::capsule) {  // lying along x
    d.shape = w.shapes().add_capsule(0.5f * size, size);
    const float s = float(std::sqrt(0.5));
    const float q[4] = {s, 0.0f, s, 0.0f};
    std::copy(q, q + 4, d.state.orientation);
  }
  d.mass = mass;
  d.friction = friction;
  std::copy(at, at + 3, d.state.position);
  if (v) std::copy(v, v + 3, d.state.velocity);
  return w.add_body(d);
}

struct Track {
  std::vector<double> x, y, z, vz, tilt;  // per step; tilt: the angle the body turned from its start (rad)
};

double angle_between(const float* q0, const float* q1) {
  const double d = std::fabs(q0[0] * q1[0] + q0[1] * q1[1] + q0[2] * q1[2] + q0[3] * q1[3]);
  return 2.0 * std::acos(std::min(1.0, d));
}

Track run(Ground g, Kind k, float size, float mass, const float at[3], const float v[3], int steps, float friction = 0.5f,
          int cells = 40, float cell = 0.5f, double tilt = 0.0) {
  World w;
  add_ground(w, g, cells, cell, tilt);
  const BodyId id = add_thing(w, k, size, mass, at, v, friction);
  Track tr;
  const BodyState s0 = w.state(id);
  for (int s = 0; s < steps; ++s) {
    w.step();
    const BodyState& b = w.state(id);
    tr.x.push_back(b.position[0]), tr.y.push_back(b.position[1]), tr.z.push_back(b.position[2]);
    tr.vz.push_back(b.velocity[2]);
    tr.tilt.push_back(angle_between(s0.orientation, b.orientation));
  }
  return tr;
}

double largest_gap(const std::vector<double>& a, const std::vector<double>& b) {
  double m = 0;
  for (size_t i = 0; i < a.size(); ++i) m = std::max(m, std::fabs(a[i] - b[i]));
  return m;
}

// Dropped bodies of three shapes, 0.1 to 1 m and 0.5 to 500 kg, at points in cells, on edges
// and on vertices of the grid: the surface gives the plane's fall, landing and rest, to a
// millimetre, and nothing drifts sideways.
TEST(TriangleSurfaces, BodiesLandAndRestOnAFlatSurfaceAsOnThePlane) {
  struct Drop {
    Kind kind;
    float size, mass, x, y;
  };
  const Drop drops[] = {
      {Kind::sphere, 0.1f, 0.5f, 0.13f, 0.27f},  {Kind::sphere, 0.5f, 50.0f, 0.0f, 0.0f},   // in a cell; on a vertex
      {Kind::box, 0.25f, 5.0f, 0.25f, 0.0f},     {Kind::box, 1.0f, 500.0f, 0.5f, 0.5f},    // on an edge; on a vertex
      {Kind::capsule, 0.3f, 2.0f, 0.1f, 0.25f},  {Kind::box, 0.1f, 0.5f, 0.37f, 0.12f}};   // across edges
  for (const Drop& d : drops)
    for (Ground g : {Ground::mesh, Ground::height_field}) {
      SCOPED_TRACE(std::string(kind_name(d.kind)) + " of " + std::to_string(d.size) + " m on a " + ground_name(g));
      const float at[3] = {d.x, d.y, 2.0f * d.size + 0.3f};
      const Track ref = run(Ground::plane, d.kind, d.size, d.mass, at, nullptr, 120);
      const Track got = run(g, d.kind, d.size, d.mass, at, nullptr, 120);
      EXPECT_LT(largest_gap(ref.z, got.z), 1e-3) << "height against the plane's, over the fall and the landing";
      EXPECT_LT(std::fabs(ref.z.back() - got.z.back()), 2e-4) << "resting height";
      EXPECT_LT(largest_gap(ref.x, got.x) + largest_gap(ref.y, got.y), 1e-3) << "sideways";
      EXPECT_LT(got.tilt.back(), 0.01) << "turned";
    }
}

// The inside edges: a box slid across a fine surface (many triangles, diagonal and square
// edges met head on and at an angle) moves as on the plane, with no bump up and no pitch; a
// sphere rolls across as on the plane.
TEST(TriangleSurfaces, NothingSnagsOnTheEdgesBetweenTriangles) {
  struct Slide {
    Kind kind;
    float size, mass, vx, vy, cell;
  };
  const Slide slides[] = {{Kind::box, 0.2f, 2.0f, 4.0f, 0.0f, 0.25f},    {Kind::box, 0.2f, 2.0f, 3.0f, 3.0f, 0.25f},
                          {Kind::box, 0.5f, 80.0f, 5.0f, 1.0f, 0.1f},    {Kind::sphere, 0.15f, 1.0f, 4.0f, 0.5f, 0.2f},
                          {Kind::capsule, 0.2f, 3.0f, 0.0f, 4.0f, 0.25f}};
  for (const Slide& s : slides)
    for (Ground g : {Ground::mesh, Ground::height_field}) {
      SCOPED_TRACE(std::string(kind_name(s.kind)) + " sliding at (" + std::to_string(s.vx) + ", " + std::to_string(s.vy) +
                   ") m/s over " + std::to_string(s.cell) + " m cells of a " + ground_name(g));
      const float h = s.kind == Kind::box ? 0.5f * s.size : s.kind == Kind::sphere ? s.size : 0.5f * s.size;
      const float at[3] = {-3.0f, -2.0f, h - 1e-4f}, v[3] = {s.vx, s.vy, 0.0f};
      const int cells = int(std::lround(16.0f / s.cell));
      const Track ref = run(Ground::plane, s.kind, s.size, s.mass, at, v, 90, 0.3f);
      const Track got = run(g, s.kind, s.size, s.mass, at, v, 90, 0.3f, cells, s.cell);
      double bump = 0, vz = 0;
      for (size_t i = 0; i < got.z.size(); ++i) bump = std::max(bump, got.z[i] - ref.z[i]), vz = std::max(vz, std::fabs(got.vz[i]));
      EXPECT_LT(bump, 5e-4) << "lifted above the plane's height by an edge";
      EXPECT_LT(vz, 0.05) << "vertical speed from an edge (m/s)";
      const double travelled = std::hypot(ref.x.back() - at[0], ref.y.back() - at[1]);
      EXPECT_LT(std::hypot(got.x.back() - ref.x.back(), got.y.back() - ref.y.back()), 0.01 * travelled) << "where it stopped";
      if (s.kind == Kind::box) EXPECT_LT(got.tilt.back(), 0.01) << "pitched by an edge";
    }
}

// A turned surface: a box sliding down a 20 degree slope made of a height field turned about
// y, against the plane of the same slope and the incline's closed form g (sin a - mu cos a).
TEST(TriangleSurfaces, ASlopeOfTrianglesIsTheInclinedPlane) {
  const double tilt = 20.0 * kPi / 180.0, mu = 0.2;
  const float at[3] = {0.0f, 0.0f, 0.0f};
  for (Ground g : {Ground::plane, Ground::mesh, Ground::height_field}) {
    SCOPED_TRACE(ground_name(g));
    World w;
    add_ground(w, g, 40, 0.5f, tilt);
    // a box of half height 0.1 resting on the slope: its centre 0.1 m off the surface along the normal
    const float n[3] = {float(std::sin(tilt)), 0.0f, float(std::cos(tilt))};
    float p[3];
    for (int k = 0; k < 3; ++k) p[k] = at[k] + (0.1f - 1e-4f) * n[k];
    BodyDesc d;
    const float h[3] = {0.2f, 0.14f, 0.1f};
    d.shape = w.shapes().add_box(h);
    d.mass = 3.0f;
    d.friction = float(mu * mu / 0.5);  // with the ground's 0.5, by the geometric mean: mu
    std::copy(p, p + 3, d.state.position);
    const float q[4] = {float(std::cos(tilt / 2)), 0.0f, float(std::sin(tilt / 2)), 0.0f};
    std::copy(q, q + 4, d.state.orientation);
    const BodyId id = w.add_body(d);
    const int steps = 60;
    for (int s = 0; s < 30; ++s) w.step();  // settled and sliding
    const BodyState a = w.state(id);
    for (int s = 30; s < steps; ++s) w.step();
    const BodyState b = w.state(id);
    // the speed down the slope (body x turned by the tilt) gained over 0.5 s
    const double down[3] = {std::cos(tilt), 0.0, -std::sin(tilt)};
    double va = 0, vb = 0;
    for (int k = 0; k < 3; ++k) va += a.velocity[k] * down[k], vb += b.velocity[k] * down[k];
    const double accel = (vb - va) / (30 * w.settings().dt), want = 9.81 * (std::sin(tilt) - mu * std::cos(tilt));
    EXPECT_NEAR(accel, want, 0.02 * want) << "sliding acceleration against the closed form";
    EXPECT_LT(std::fabs(b.position[1]), 1e-3) << "drifted across the slope";
  }
}

// One-sided: a ball overlapping the surface from behind (its centre below the triangles) feels
// nothing and falls away as in free flight; one resting on the front is held.
TEST(TriangleSurfaces, TrianglesHaveOnlyAFront) {
  for (Ground g : {Ground::mesh, Ground::height_field}) {
    SCOPED_TRACE(ground_name(g));
    World w;
    add_ground(w, g, 10, 0.5f);
    const float below[3] = {0.1f, 0.2f, -0.1f}, above[3] = {1.0f, 0.3f, 0.2f - 1e-4f};
    const BodyId behind = add_thing(w, Kind::sphere, 0.2f, 1.0f, below);
    const BodyId front = add_thing(w, Kind::sphere, 0.2f, 1.0f, above);
    const int n = 30;
    for (int s = 0; s < n; ++s) w.step();
    // the step's own free fall: z0 - g h^2 n (n + 1) / 2
    const double h = w.settings().dt, fall = 9.81 * h * h * n * (n + 1) / 2;
    EXPECT_NEAR(w.state(behind).position[2], -0.1 - fall, 1e-4) << "the one behind the surface fell freely";
    EXPECT_NEAR(w.state(front).position[2], 0.2f, 2e-3) << "the one on the front rests on it";
  }
}

// A mesh shaped as a step: a floor, a vertical riser and a raised floor (its top edge a convex
// crease, active). A box slid at the riser stops against it (the riser's face pushes it back);
// a box slid off the top's border edge falls; the crease between floor and riser (hollow) and
// the inside edges of each flat part are inactive, the top's crease and border active.
TEST(TriangleSurfaces, CreasesAndBordersStillPush) {
  // floor z = 0 for x < 0, riser at x = 0 up to z = 0.5, top z = 0.5 for x in 0..2, each 4 m wide in y
  const std::vector<float> v = {-3, -2, 0, 0, -2, 0, 0, 2, 0, -3, 2, 0,        // floor
                                0, -2, 0.5f, 0, 2, 0.5f,                     // riser top edge
                                2, -2, 0.5f, 2, 2, 0.5f};                    // top
  const std::vector<int32_t> t = {0, 1, 2, 0, 2, 3,   // floor, facing +z
                                  1, 4, 5, 1, 5, 2,   // riser, facing -x
                                  4, 6, 7, 4, 7, 5};  // top, facing +z
  World w;
  BodyDesc gd;
  gd.shape = w.shapes().add_mesh(v.data(), int(v.size() / 3), t.data(), int(t.size() / 3));
  gd.is_static = true;
  w.add_body(gd);
  const spu::MeshView& m = w.shapes().view(gd.shape).mesh;
  // each triangle's edges by their vertices: which are active
  auto active = [&](int32_t a, int32_t b) {
    for (int k = 0; k < m.num_triangles; ++k)
      for (int e = 0; e < 3; ++e) {
        const int32_t x = m.triangles[3 * k + e], y = m.triangles[3 * k + (e + 1) % 3];
        if ((x == a && y == b) || (x == b && y == a)) return (m.edge_flags[k] >> e & 1) != 0;
      }
    ADD_FAILURE() << "no edge " << a << "-" << b;
    return false;
  };
  EXPECT_FALSE(active(0, 2)) << "inside edge of the floor";
  EXPECT_FALSE(active(1, 2)) << "the hollow crease between floor and riser";
  EXPECT_TRUE(active(4, 5)) << "the convex crease at the top of the riser";
  EXPECT_TRUE(active(6, 7)) << "the top's border";
  EXPECT_FALSE(active(4, 7)) << "inside edge of the top";

  const float at[3] = {-1.5f, 0.0f, 0.15f - 1e-4f}, v0[3] = {4.0f, 0.0f, 0.0f};
  const BodyId box = add_thing(w, Kind::box, 0.15f, 2.0f, at, v0, 0.0f);  // frictionless: only the riser stops it
  const float top[3] = {1.0f, 0.0f, 0.5f + 0.075f - 1e-4f}, v1[3] = {3.0f, 0.0f, 0.0f};
  const BodyId off = add_thing(w, Kind::box, 0.15f, 2.0f, top, v1, 0.0f);
  for (int s = 0; s < 90; ++s) w.step();
  const BodyState b = w.state(box);
  EXPECT_LT(b.position[0], 0.0f) << "went through the riser";
  EXPECT_LT(b.position[2], 0.2f) << "climbed the riser";
  EXPECT_LT(w.state(off).position[2], 0.3f) << "the box slid off the top's border fell";
}

// The hierarchy finds exactly the triangles a brute-force test of every triangle's box finds,
// for random boxes on random surfaces, and far fewer than all of them for a small box.
TEST(TriangleSurfaces, TheHierarchyFindsWhatBruteForceFinds) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(-10.0f, 10.0f), h(-1.0f, 1.0f);
  for (int trial = 0; trial < 4; ++trial) {
    ShapeDictionary d;
    const int rows = 20 + 13 * trial, cols = 30 + 7 * trial;
    std::vector<float> heights(size_t(rows) * cols);
    for (float& x : heights) x = h(rng);
    const float spacing[2] = {0.5f, 0.37f};
    const spu::MeshView& m = d.view(d.add_height_field(rows, cols, spacing, heights.data())).mesh;
    size_t visited_small = 0;
    for (int q = 0; q < 200; ++q) {
      const double c[3] = {u(rng), u(rng), h(rng)}, r = q % 2 ? 0.3 : 3.0;
      const double lo[3] = {c[0] - r, c[1] - r, c[2] - r}, hi[3] = {c[0] + r, c[1] + r, c[2] + r};
      std::vector<int32_t> found;
      spu::visit_triangles_in_box(m, lo, hi, [&](int32_t t) { return found.push_back(t), true; });
      std::vector<int32_t> brute;
      for (int t = 0; t < m.num_triangles; ++t) {
        bool in = true;
        for (int k = 0; k < 3; ++k) {
          double tl = 1e300, th = -1e300;
          for (int c3 = 0; c3 < 3; ++c3) {
            const double x = m.vertices[3 * m.triangles[3 * t + c3] + k];
            tl = std::min(tl, x), th = std::max(th, x);
          }
          in = in && tl <= hi[k] && th >= lo[k];
        }
        if (in) brute.push_back(t);
      }
      // every triangle whose own box meets the query is visited (leaves may bring neighbours)
      std::sort(found.begin(), found.end());
      EXPECT_TRUE(std::includes(found.begin(), found.end(), brute.begin(), brute.end())) << "query " << q;
      EXPECT_TRUE(std::adjacent_find(found.begin(), found.end()) == found.end()) << "a triangle visited twice";
      if (q % 2) visited_small += found.size();
    }
    EXPECT_LT(visited_small / 100.0, 0.05 * m.num_triangles) << "a small box visits few of the triangles";
  }
}

// Rays against a random height field: the first front hit, as a loop over every triangle
// finds it, and none from below.
TEST(TriangleSurfaces, RaysHitTheFirstFrontTriangle) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> u(-6.0f, 6.0f), h(-0.8f, 0.8f);
  ShapeDictionary d;
  std::vector<float> heights(30 * 40);
  for (float& x : heights) x = h(rng);
  const float spacing[2] = {0.4f, 0.3f};
  const spu::ShapeView& view = d.view(d.add_height_field(30, 40, spacing, heights.data()));
  spu::Pose pose;
  pose.position[0] = 1.0f, pose.position[2] = 0.5f;
  pose.orientation[0] = float(std::cos(0.2)), pose.orientation[3] = float(std::sin(0.2));  // turned about z
  pose.scale = 1.5f;
  int hits = 0;
  for (int q = 0; q < 500; ++q) {
    const Vec3d o{u(rng), u(rng), q % 5 ? 4.0 : -4.0};
    Vec3d dir{0.3 * h(rng), 0.3 * h(rng), q % 5 ? -1.0 : 1.0};
    dir = dir * (1.0 / cellphys::norm(dir));
    ShapeRayHit hit;
    const bool got = ray_shape(view, pose, o, dir, 20.0, hit);
    // brute force, in world coordinates
    double best = 1e300;
    const spu::MeshView& m = view.mesh;
    const double qw = pose.orientation[0], qz = pose.orientation[3];  // the pose's own float turn
    const double c = (qw * qw - qz * qz) / (qw * qw + qz * qz), s = 2 * qw * qz / (qw * qw + qz * qz);
    auto world = [&](const float* p) {
      const double x = 1.5 * p[0], y = 1.5 * p[1], z = 1.5 * p[2];
      return Vec3d{1.0 + c * x - s * y, s * x + c * y, 0.5 + z};
    };
    for (int t = 0; t < m.num_triangles; ++t) {
      const Vec3d a = world(m.vertices + 3 * m.triangles[3 * t]), b = world(m.vertices + 3 * m.triangles[3 * t + 1]),
                  cc = world(m.vertices + 3 * m.triangles[3 * t + 2]);
      const Vec3d n = cellphys::cross(b - a, cc - a);
      if (cellphys::dot(n, dir) >= 0) continue;  // from behind
      const double at = cellphys::dot(n, a - o) / cellphys::dot(n, dir);
      if (at < 0 || at > 20.0) continue;
      const Vec3d p = o + dir * at;
      if (cellphys::dot(cellphys::cross(b - a, p - a), n) < 0 || cellphys::dot(cellphys::cross(cc - b, p - b), n) < 0 ||
          cellphys::dot(cellphys::cross(a - cc, p - cc), n) < 0)
        continue;
      best = std::min(best, at);
    }
    ASSERT_EQ(got, best < 1e300) << "ray " << q;
    if (got) {
      ++hits;
      EXPECT_NEAR(hit.distance, best, 1e-6) << "ray " << q;
      EXPECT_LT(cellphys::dot(hit.normal, dir), 0.0);
    }
  }
  EXPECT_GT(hits, 300) << "most rays from above hit";
}

// The world's queries on a terrain: a ray down finds the height field's surface, a sphere
// swept down stops on it (never past), an overlap test finds it under a box that reaches it.
TEST(TriangleSurfaces, QueriesFindTheTerrain) {
  World w;
  const int n = 21;
  std::vector<float> heights(size_t(n) * n);
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) heights[size_t(i) * n + j] = 0.3f * std::sin(0.5f * j) + 0.2f * std::cos(0.4f * i);
  const float spacing[2] = {0.5f, 0.5f};
  BodyDesc gd;
  gd.shape = w.shapes().add_height_field(n, n, spacing, heights.data());
  gd.is_static = true;
  const BodyId ground = w.add_body(gd);
  // the surface's height at a grid point (i, j): x = (j - 10) / 2, y = (i - 10) / 2
  const int i = 7, j = 12;
  const float x = (j - 10) * 0.5f, y = (i - 10) * 0.5f, z = heights[size_t(i) * n + j];
  const float origin[3] = {x, y, 5.0f}, down[3] = {0.0f, 0.0f, -1.0f};
  const auto hit = w.ray_cast(origin, down, 100.0f);
  ASSERT_TRUE(hit.has_value());
  EXPECT_EQ(hit->body, ground);
  EXPECT_NEAR(hit->point[2], z, 1e-5);
  const float up_origin[3] = {x, y, -5.0f}, up[3] = {0.0f, 0.0f, 1.0f};
  EXPECT_FALSE(w.ray_cast(up_origin, up, 100.0f).has_value()) << "from below: one-sided";
  const float r = 0.25f, start[3] = {x, y, 3.0f}, q[4] = {1, 0, 0, 0};
  const auto swept = w.shape_cast(QueryShape::sphere(r), start, q, down, 100.0f);
  ASSERT_TRUE(swept.has_value());
  EXPECT_EQ(swept->body, ground);
  // the ball's lowest point stops on or just above the surface near the vertex it comes down on
  const float rest = start[2] - swept->distance;
  EXPECT_GE(rest - r, z - 1e-4f);
  EXPECT_LT(rest - r, z + 0.3f);
  const float centre[3] = {x, y, z + 0.1f}, small[3] = {0.2f, 0.2f, 0.2f}, high[3] = {x, y, z + 1.0f};
  EXPECT_EQ(w.overlap_box(centre, small, q), std::vector<BodyId>{ground});
  EXPECT_TRUE(w.overlap_box(high, small, q).empty());
}

// Bad input is refused with the shape kind, the item and why; a triangle with no area is left
// out and counted; a mesh or height field cannot be a dynamic body.
TEST(TriangleSurfaces, BadSurfacesAreRefusedByName) {
  ShapeDictionary d;
  const std::vector<float> v = {0, 0, 0, 1, 0, 0, 0, 1, 0, 2, 0, 0};
  auto refused = [&](std::vector<int32_t> t, const std::string& says) {
    try {
      d.add_mesh(v.data(), 4, t.data(), int(t.size() / 3));
      ADD_FAILURE() << "accepted: " << says;
    } catch (const ShapeError& e) {
      EXPECT_NE(std::string(e.what()).find(says), std::string::npos) << e.what();
    }
  };
  refused({0, 1, 4}, "mesh: triangle 0: vertex index 4 out of range");
  refused({0, 1, 2, 1, 1, 2}, "mesh: triangle 1 repeats a vertex");
  refused({0, 1, 3}, "mesh: no triangle has an area");
  const std::vector<int32_t> with_sliver = {0, 1, 2, 0, 1, 3};
  const uint32_t ok = d.add_mesh(v.data(), 4, with_sliver.data(), 2);
  EXPECT_EQ(d.surface_input(ok).dropped_triangles, 1);
  EXPECT_EQ(d.surface_input(ok).num_triangles, 1);
  const std::vector<float> nan = {0, 0, 0, 1, 0, 0, 0, NAN, 0};
  try {
    d.add_mesh(nan.data(), 3, with_sliver.data(), 1);
    ADD_FAILURE() << "a NaN vertex accepted";
  } catch (const ShapeError& e) {
    EXPECT_NE(std::string(e.what()).find("mesh: vertex 2 is not finite"), std::string::npos) << e.what();
  }
  const float h[4] = {0, 0, 0, 0}, spacing[2] = {1, 0};
  EXPECT_THROW(d.add_height_field(2, 2, spacing, h), ShapeError);
  const float fine[2] = {1, 1};
  EXPECT_THROW(d.add_height_field(1, 4, fine, h), ShapeError);

  World w;
  BodyDesc dyn;
  dyn.shape = w.shapes().add_mesh(v.data(), 4, with_sliver.data(), 2);
  dyn.mass = 1.0f;
  const BodyId id = w.add_body(dyn);  // a surface is static whatever it is asked to be, as a plane is
  EXPECT_TRUE(w.is_static(id));
}

// Scene files: a mesh inline and from an OBJ file beside the scene, and a height field, read,
// built, written and read back equal; a bad OBJ line is named. A snapshot of a world on a
// terrain restores and steps on bit for bit.
TEST(TriangleSurfaces, SceneFilesAndSnapshotsCarrySurfaces) {
  const std::string dir = ::testing::TempDir();
  {
    std::ofstream obj(dir + "/ramp.obj");
    obj << "# a ramp\nv -2 -2 0\nv 2 -2 1\nv 2 2 1\nv -2 2 0\nvt 0 0\nf 1/1 2/1 3/1 4/1\n";
  }
  const std::string scene_text = R"({
    "shapes": [
      {"name": "ramp", "type": "mesh", "obj": "ramp.obj"},
      {"name": "tri", "type": "mesh", "vertices": [[0,0,0],[1,0,0],[0,1,0]], "triangles": [[0,1,2]]},
      {"name": "hills", "type": "height_field", "rows": 3, "columns": 4, "spacing": [1, 2],
       "heights": [0, 0.1, 0.2, 0.1, 0, 0.3, 0.1, 0, 0.2, 0, 0.1, 0.4]},
      {"name": "ball", "type": "sphere", "radius": 0.2}
    ],
    "bodies": [
      {"id": "ramp", "shape": "ramp", "static": true, "position": [0, 0, 0]},
      {"id": "hills", "shape": "hills", "static": true, "position": [10, 0, 0]},
      {"id": "b1", "shape": "ball", "mass": 1, "position": [0.5, 0.3, 1.5]},
      {"id": "b2", "shape": "ball", "mass": 1, "position": [10.2, 0.4, 1.0]}
    ]
  })";
  const std::string file = dir + "/terrain_scene.json";
  {
    std::ofstream out(file);
    out << scene_text;
  }
  const cellphys::scene::SceneDesc s = cellphys::scene::load_scene(file);
  ASSERT_EQ(s.shapes[0].triangles.size(), 6u) << "the OBJ quad, fanned into two triangles";
  EXPECT_EQ(s.shapes[2].heights.size(), 12u);
  const cellphys::scene::SceneDesc back = cellphys::scene::parse_scene(cellphys::scene::write_scene(s), "written");
  EXPECT_TRUE(back.shapes == s.shapes) << "written and read back";
  cellphys::scene::BuiltScene built = cellphys::scene::build_world(s);
  World& w = *built.world;
  for (int k = 0; k < 40; ++k) w.step();
  EXPECT_GT(w.state(built.bodies[2]).position[2], 0.3f) << "the ball landed on the ramp, not through it";
  const std::vector<unsigned char> snap = w.snapshot();
  auto r = World::restore(snap.data(), snap.size());
  for (int k = 0; k < 30; ++k) w.step(), r->step();
  EXPECT_EQ(w.state_hash(), r->state_hash()) << "the restored terrain world steps on bit for bit";

  try {
    cellphys::scene::parse_scene(R"({"shapes": [{"name": "m", "type": "mesh", "obj": "missing.obj"}]})", dir + "/x.json");
    ADD_FAILURE() << "a missing OBJ accepted";
  } catch (const cellphys::scene::SceneError& e) {
    EXPECT_NE(std::string(e.what()).find("shapes[0].obj"), std::string::npos) << e.what();
  }
  {
    std::ofstream obj(dir + "/bad.obj");
    obj << "v 0 0 0\nv 1 0 0\nf 1 2 7\n";
  }
  try {
    cellphys::scene::parse_scene(R"({"shapes": [{"name": "m", "type": "mesh", "obj": "bad.obj"}]})", dir + "/x.json");
    ADD_FAILURE() << "a bad OBJ accepted";
  } catch (const cellphys::scene::SceneError& e) {
    EXPECT_NE(std::string(e.what()).find("bad.obj:3: face corner 7 names no vertex"), std::string::npos) << e.what();
  }
  try {
    cellphys::scene::parse_scene(
        R"({"shapes": [{"name": "h", "type": "height_field", "rows": 2, "columns": 2, "spacing": [1, 1], "heights": [0, 1, 2]}]})",
        "h.json");
    ADD_FAILURE() << "a short height field accepted";
  } catch (const cellphys::scene::SceneError& e) {
    EXPECT_NE(std::string(e.what()).find("shapes[0].heights"), std::string::npos) << e.what();
  }
}

}  // namespace
