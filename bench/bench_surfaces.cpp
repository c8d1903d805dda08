// Level geometry's costs (runtime/ppe/triangle_surface.h): a rolling height field of 64 x 64
// to 1024 x 1024 samples (8 thousand to 2 million triangles), 0.5 m apart.
//  - building one (checks, active edges, the hierarchy);
//  - a body's box against the hierarchy, and against every triangle's box (brute force);
//  - rays cast down onto it through the hierarchy; rays per second;
//  - the narrow phase of a box resting on it against the same box on a plane;
//  - a world step with 200 bodies on the terrain against the same bodies on a plane.
#include <benchmark/benchmark.h>

#include <array>
#include <cmath>
#include <map>
#include <memory>
#include <random>
#include <vector>

#include "runtime/ppe/shape_ray.h"
#include "runtime/ppe/world.h"
#include "runtime/spu/narrow_phase.h"
#include "runtime/spu/surface_tree.h"

namespace {

using namespace cellphys;

float height(double x, double y) { return float(0.8 * std::sin(0.35 * x) * std::cos(0.3 * y)); }

struct Terrain {
  ppe::ShapeDictionary shapes;
  uint32_t field = 0;
  double half = 0;  // half its side (m)
};

Terrain& terrain(int n) {
  static std::map<int, std::unique_ptr<Terrain>> made;
  auto& t = made[n];
  if (t) return *t;
  t = std::make_unique<Terrain>();
  std::vector<float> h(size_t(n) * n);
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) h[size_t(i) * n + j] = height((j - 0.5 * (n - 1)) * 0.5, (i - 0.5 * (n - 1)) * 0.5);
  const float spacing[2] = {0.5f, 0.5f};
  t->field = t->shapes.add_height_field(n, n, spacing, h.data());
  t->half = 0.25 * (n - 1);
  return *t;
}

std::vector<std::array<double, 3>> points(const Terrain& t, int count) {
  std::mt19937 g(5);
  std::uniform_real_distribution<double> u(-t.half, t.half);
  std::vector<std::array<double, 3>> p(count);
  for (auto& x : p) x = {u(g), u(g), 0.0}, x[2] = height(x[0], x[1]);
  return p;
}

// Adding the field to a dictionary: its checks, active edges and hierarchy.
void BM_SurfaceBuild(benchmark::State& state) {
  const int n = int(state.range(0));
  std::vector<float> h(size_t(n) * n);
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) h[size_t(i) * n + j] = height((j - 0.5 * (n - 1)) * 0.5, (i - 0.5 * (n - 1)) * 0.5);
  const float spacing[2] = {0.5f, 0.5f};
  for (auto _ : state) {
    ppe::ShapeDictionary d;
    benchmark::DoNotOptimize(d.add_height_field(n, n, spacing, h.data()));
  }
}
BENCHMARK(BM_SurfaceBuild)->ArgName("samples")->Arg(256)->Arg(1024)->Unit(benchmark::kMillisecond);

// A 1 m box around a point on the surface: the triangles its leaves hold.
void BM_SurfaceBoxQuery(benchmark::State& state) {
  const Terrain& t = terrain(int(state.range(0)));
  const spu::MeshView& m = t.shapes.view(t.field).mesh;
  const auto at = points(t, 1024);
  size_t k = 0, found = 0;
  for (auto _ : state) {
    const auto& c = at[k++ % at.size()];
    const double lo[3] = {c[0] - 0.5, c[1] - 0.5, c[2] - 0.5}, hi[3] = {c[0] + 0.5, c[1] + 0.5, c[2] + 0.5};
    spu::visit_triangles_in_box(m, lo, hi, [&](int32_t) { return ++found, true; });
  }
  benchmark::DoNotOptimize(found);
  state.counters["triangles"] = m.num_triangles;
  state.counters["visited"] = double(found) / double(state.iterations());
}
BENCHMARK(BM_SurfaceBoxQuery)->ArgName("samples")->Arg(64)->Arg(256)->Arg(1024);

void BM_SurfaceBoxQueryBruteForce(benchmark::State& state) {
  const Terrain& t = terrain(int(state.range(0)));
  const spu::MeshView& m = t.shapes.view(t.field).mesh;
  const auto at = points(t, 1024);
  size_t k = 0, found = 0;
  for (auto _ : state) {
    const auto& c = at[k++ % at.size()];
    for (int tri = 0; tri < m.num_triangles; ++tri) {
      bool in = true;
      for (int a = 0; a < 3 && in; ++a) {
        float lo = 1e30f, hi = -1e30f;
        for (int v = 0; v < 3; ++v) {
          const float x = m.vertices[3 * m.triangles[3 * tri + v] + a];
          lo = std::min(lo, x), hi = std::max(hi, x);
        }
        in = lo <= c[a] + 0.5 && hi >= c[a] - 0.5;
      }
      found += in;
    }
  }
  benchmark::DoNotOptimize(found);
  state.counters["triangles"] = m.num_triangles;
}
BENCHMARK(BM_SurfaceBoxQueryBruteForce)->ArgName("samples")->Arg(64)->Arg(256);

// Rays from 10 m up, straight down and tilted, onto the terrain.
void BM_SurfaceRay(benchmark::State& state) {
  const Terrain& t = terrain(int(state.range(0)));
  const spu::ShapeView& v = t.shapes.view(t.field);
  const auto at = points(t, 4096);
  const spu::Pose pose;
  size_t k = 0, hits = 0;
  for (auto _ : state) {
    const auto& c = at[k++ % at.size()];
    const double tilt = 0.2 * double(k % 7) / 7.0;
    const Vec3d o{c[0], c[1], 10.0}, d = Vec3d{tilt, 0.5 * tilt, -1.0} * (1.0 / std::sqrt(1 + 1.25 * tilt * tilt));
    ppe::ShapeRayHit hit;
    hits += ppe::ray_shape(v, pose, o, d, 100.0, hit);
  }
  benchmark::DoNotOptimize(hits);
  state.SetItemsProcessed(int64_t(state.iterations()));
  state.counters["hit_fraction"] = double(hits) / double(state.iterations());
}
BENCHMARK(BM_SurfaceRay)->ArgName("samples")->Arg(64)->Arg(256)->Arg(1024);

// The narrow phase of a 0.5 m box resting (1 mm deep) on the terrain, or on a plane.
void BM_BoxOnSurface(benchmark::State& state) {
  Terrain& t = terrain(256);
  const bool plane = state.range(0) == 0;
  const float h[3] = {0.25f, 0.25f, 0.25f}, up[3] = {0, 0, 1};
  static const uint32_t box = t.shapes.add_box(h), flat = t.shapes.add_plane(up, 0.0f);
  const auto at = points(t, 256);
  size_t k = 0, n = 0;
  for (auto _ : state) {
    const auto& c = at[k++ % at.size()];
    spu::Pose p;
    p.position[0] = float(c[0]), p.position[1] = float(c[1]), p.position[2] = plane ? 0.249f : float(c[2]) + 0.249f;
    spu::ContactPoint cp[spu::kMaxManifoldPoints];
    n += spu::collide(t.shapes.view(box), p, t.shapes.view(plane ? flat : t.field), spu::Pose{}, 0.01f, cp);
  }
  benchmark::DoNotOptimize(n);
  state.SetLabel(plane ? "plane" : "height field 256 x 256");
}
BENCHMARK(BM_BoxOnSurface)->ArgName("terrain")->Arg(0)->Arg(1);

// 200 boxes and balls dropped on the terrain (or on a plane), stepped 120 steps: ms a step.
void BM_StepOnSurface(benchmark::State& state) {
  const bool plane = state.range(0) == 0;
  for (auto _ : state) {
    state.PauseTiming();
    ppe::World w;
    ppe::BodyDesc g;
    g.is_static = true;
    const float up[3] = {0, 0, 1}, spacing[2] = {0.5f, 0.5f};
    const int n = 81;
    std::vector<float> hs(size_t(n) * n);
    for (int i = 0; i < n; ++i)
      for (int j = 0; j < n; ++j) hs[size_t(i) * n + j] = height((j - 40) * 0.5, (i - 40) * 0.5);
    g.shape = plane ? w.shapes().add_plane(up, 0.0f) : w.shapes().add_height_field(n, n, spacing, hs.data());
    w.add_body(g);
    const float half[3] = {0.2f, 0.15f, 0.1f};
    const uint32_t box = w.shapes().add_box(half), ball = w.shapes().add_sphere(0.2f);
    for (int k = 0; k < 200; ++k) {
      ppe::BodyDesc b;
      b.shape = k % 2 ? box : ball;
      b.mass = 2.0f;
      const double x = -15.0 + 30.0 * ((k * 37) % 200) / 200.0, y = -15.0 + 1.5 * (k / 10);
      b.state.position[0] = float(x), b.state.position[1] = float(y);
      b.state.position[2] = (plane ? 0.0f : height(x, y)) + 0.6f;
      w.add_body(b);
    }
    state.ResumeTiming();
    for (int s = 0; s < 120; ++s) w.step();
  }
  state.SetLabel(plane ? "plane" : "height field 81 x 81");
}
BENCHMARK(BM_StepOnSurface)->ArgName("terrain")->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->Iterations(3);

}  // namespace


