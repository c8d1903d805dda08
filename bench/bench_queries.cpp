// World queries between steps (runtime/ppe/world_queries.cpp) on the sparse world of
// testing/scenes.h (boxes, spheres, capsules and hulls on a ground plane, about 1.5 m apart),
// at 1,000 and 100,000 bodies, after one step (half the bodies are falling, half at rest):
//  - ray casts of 20 m from 1 m above the ground in random directions, through the query tree
//    and by a brute-force loop over every body with the same exact test; rays per second;
//  - ray_cast_all over the same rays;
//  - sphere (r = 2 m) and box (2 m x 2 m x 1 m, turned) overlap queries, tree and brute force;
//  - capsule sweeps of 10 m;
//  - the tree brought up to date after a step (the first query after it pays this).
// The world and its rays are made once per size, outside the timing.
#include <benchmark/benchmark.h>

#include <cmath>
#include <map>
#include <memory>
#include <random>
#include <vector>

#include "runtime/ppe/shape_distance.h"
#include "runtime/ppe/shape_ray.h"
#include "runtime/ppe/world.h"
#include "testing/scenes.h"

namespace {

using namespace cellphys;
using namespace cellphys::testing;
using ppe::QueryHit;
using ppe::QueryShape;

struct Ray {
  float origin[3], dir[3];
};

struct Scene {
  std::unique_ptr<World> world;
  std::vector<Ray> rays;
  float area = 0;
};

// The sparse world of n bodies (cells of 1.5 m), stepped once, and 4,096 rays over it.
Scene& scene(int n) {
  static std::map<int, Scene> scenes;
  Scene& s = scenes[n];
  if (s.world) return s;
  s.world = std::make_unique<World>();
  s.area = 1.5f * std::ceil(std::sqrt(float(n)));
  sparse_world(*s.world, n, s.area, 1);
  s.world->step();
  std::mt19937 g(7);
  auto uniform = [&](double lo, double hi) { return lo + (hi - lo) * (double(g()) / 4294967296.0); };
  for (int i = 0; i < 4096; ++i) {
    Ray r;
    r.origin[0] = float(uniform(-s.area / 2, s.area / 2));
    r.origin[1] = float(uniform(-s.area / 2, s.area / 2));
    r.origin[2] = 1.0f;
    const double a = uniform(0, 6.283185307179586), down = uniform(-0.3, 0.1);
    r.dir[0] = float(std::cos(a)), r.dir[1] = float(std::sin(a)), r.dir[2] = float(down);
    s.rays.push_back(r);
  }
  return s;
}

spu::Pose pose_of_body(const World& w, BodyId id) {
  spu::Pose p;
  const ppe::BodyState st = w.state(id);
  std::copy(st.position, st.position + 3, p.position);
  std::copy(st.orientation, st.orientation + 4, p.orientation);
  p.scale = w.scale(id);
  return p;
}

// Per body, what the brute-force loops read, gathered once (as a loop in a server would keep it).
struct Flat {
  std::vector<const spu::ShapeView*> views;
  std::vector<spu::Pose> poses;
  explicit Flat(const World& w) {
    for (BodyId id : w.bodies()) views.push_back(&w.shapes().view(w.shape(id))), poses.push_back(pose_of_body(w, id));
  }
};

void rays_per_second(benchmark::State& state, int64_t hits) {
  state.SetItemsProcessed(state.iterations());
  state.counters["hit_fraction"] = benchmark::Counter(double(hits) / double(state.iterations()));
}

void BM_RayCast(benchmark::State& state) {
  Scene& s = scene(int(state.range(0)));
  size_t i = 0;
  int64_t hits = 0;
  for (auto _ : state) {
    const Ray& r = s.rays[i++ & 4095];
    const std::optional<QueryHit> h = s.world->ray_cast(r.origin, r.dir, 20.0f);
    hits += h.has_value();
    benchmark::DoNotOptimize(h);
  }
  rays_per_second(state, hits);
}
BENCHMARK(BM_RayCast)->ArgName("bodies")->Arg(1000)->Arg(100000);

void BM_RayCastBruteForce(benchmark::State& state) {
  Scene& s = scene(int(state.range(0)));
  const Flat flat(*s.world);
  size_t i = 0;
  int64_t hits = 0;
  for (auto _ : state) {
    const Ray& r = s.rays[i++ & 4095];
    const Vec3d o = Vec3d::load(r.origin), d = Vec3d::load(r.dir) * (1.0 / norm(Vec3d::load(r.dir)));
    double best = 20.0;
    bool hit = false;
    ppe::ShapeRayHit h;
    for (size_t b = 0; b < flat.views.size(); ++b)
      if (ppe::ray_shape(*flat.views[b], flat.poses[b], o, d, best, h)) best = h.distance, hit = true;
    hits += hit;
    benchmark::DoNotOptimize(best);
  }
  rays_per_second(state, hits);
}
BENCHMARK(BM_RayCastBruteForce)->ArgName("bodies")->Arg(1000)->Arg(100000);

void BM_RayCastAll(benchmark::State& state) {
  Scene& s = scene(int(state.range(0)));
  size_t i = 0;
  int64_t hits = 0;
  for (auto _ : state) {
    const Ray& r = s.rays[i++ & 4095];
    const std::vector<QueryHit> h = s.world->ray_cast_all(r.origin, r.dir, 20.0f);
    hits += !h.empty();
    benchmark::DoNotOptimize(h.data());
  }
  rays_per_second(state, hits);
}
BENCHMARK(BM_RayCastAll)->ArgName("bodies")->Arg(1000)->Arg(100000);

void BM_OverlapSphere(benchmark::State& state) {
  Scene& s = scene(int(state.range(0)));
  size_t i = 0;
  double found = 0;
  for (auto _ : state) {
    const std::vector<BodyId> ids = s.world->overlap_sphere(s.rays[i++ & 4095].origin, 2.0f);
    found += double(ids.size());
  }
  state.SetItemsProcessed(state.iterations());
  state.counters["bodies_found"] = benchmark::Counter(found / double(state.iterations()));
}
BENCHMARK(BM_OverlapSphere)->ArgName("bodies")->Arg(1000)->Arg(100000);

void BM_OverlapSphereBruteForce(benchmark::State& state) {
  Scene& s = scene(int(state.range(0)));
  const Flat flat(*s.world);
  spu::ShapeView ball;
  ball.type = spu::ShapeType::sphere;
  ball.radius = 2.0f;
  size_t i = 0;
  double found = 0;
  for (auto _ : state) {
    spu::Pose p;
    std::copy(s.rays[i & 4095].origin, s.rays[i & 4095].origin + 3, p.position);
    ++i;
    size_t n = 0;
    for (size_t b = 0; b < flat.views.size(); ++b) n += ppe::shapes_overlap(ball, p, *flat.views[b], flat.poses[b]);
    found += double(n);
  }
  state.SetItemsProcessed(state.iterations());
  state.counters["bodies_found"] = benchmark::Counter(found / double(state.iterations()));
}
BENCHMARK(BM_OverlapSphereBruteForce)->ArgName("bodies")->Arg(1000)->Arg(100000);

void BM_OverlapBox(benchmark::State& state) {
  Scene& s = scene(int(state.range(0)));
  const float half[3] = {1.0f, 1.0f, 0.5f}, q[4] = {0.9238795f, 0.0f, 0.0f, 0.3826834f};  // 45 degrees about z
  size_t i = 0;
  double found = 0;
  for (auto _ : state) found += double(s.world->overlap_box(s.rays[i++ & 4095].origin, half, q).size());
  state.SetItemsProcessed(state.iterations());
  state.counters["bodies_found"] = benchmark::Counter(found / double(state.iterations()));
}
BENCHMARK(BM_OverlapBox)->ArgName("bodies")->Arg(1000)->Arg(100000);

void BM_ShapeCastCapsule(benchmark::State& state) {
  Scene& s = scene(int(state.range(0)));
  const QueryShape capsule = QueryShape::capsule(0.3f, 0.6f);  // a standing character
  const float q[4] = {1, 0, 0, 0};
  size_t i = 0;
  int64_t hits = 0;
  for (auto _ : state) {
    const Ray& r = s.rays[i++ & 4095];
    const float start[3] = {r.origin[0], r.origin[1], 1.2f}, dir[3] = {r.dir[0], r.dir[1], 0.0f};
    hits += s.world->shape_cast(capsule, start, q, dir, 10.0f).has_value();
  }
  rays_per_second(state, hits);
}
BENCHMARK(BM_ShapeCastCapsule)->ArgName("bodies")->Arg(1000)->Arg(100000);

// One step untimed, then one ray timed: the ray pays for bringing the tree up to date over
// every body (new boxes for those that moved, a refit or a rebuild).
void BM_TreeUpdateAfterStep(benchmark::State& state) {
  Scene& s = scene(int(state.range(0)));
  const Ray& r = s.rays[0];
  double step_ms = 0;
  for (auto _ : state) {
    state.PauseTiming();
    step_ms += s.world->step().times.total_ms;
    state.ResumeTiming();
    benchmark::DoNotOptimize(s.world->ray_cast(r.origin, r.dir, 20.0f));
  }
  int awake = 0;
  for (BodyId id : s.world->bodies()) awake += s.world->is_awake(id) && !s.world->is_static(id);
  state.counters["awake"] = benchmark::Counter(awake);
  state.counters["step_ms"] = benchmark::Counter(step_ms, benchmark::Counter::kAvgIterations);  // the step itself, for scale
}
BENCHMARK(BM_TreeUpdateAfterStep)->ArgName("bodies")->Arg(1000)->Arg(100000)->Iterations(20)->Unit(benchmark::kMicrosecond);

}  // namespace
