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

}  // namespace
