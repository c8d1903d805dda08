// Narrow-phase cost per pair: the resting contacts a scene is made of (a box on a box with a
// 4-point manifold, a box on the ground, spheres), 20-vertex hulls (a dodecahedron, with
// pentagon faces, and a triangulated random hull), and collide_batch over 1000 box pairs.
// Each benchmark cycles through a fixed set of slightly different poses so the branch
// predictor does not learn one configuration; time is per pair (items/s = pairs/s).
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include "runtime/spu/narrow_phase.h"

namespace {

using namespace cellphys::spu;

struct V {
  double x, y, z;
};
V sub(V a, V b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
double dot(V a, V b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
V cross(V a, V b) { return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x}; }

/// A hull owning its arrays, built by brute force from points in convex position (every
/// plane through three points with all points on one side; coplanar points share a face).
struct Hull {
  std::vector<float> vertices, planes;
  std::vector<int32_t> face_start{0}, face_vertices, edges;
  ShapeView shape() const {
    ShapeView s;
    s.type = ShapeType::hull;
    s.hull = {int32_t(vertices.size() / 3), vertices.data(), int32_t(planes.size() / 4), planes.data(),
              face_start.data(), face_vertices.data(), int32_t(edges.size() / 2), edges.data()};
    return s;
  }
};

Hull hull_from_points(const std::vector<V>& p, double eps) {
  const int n = int(p.size());
  Hull h;
  for (const V& v : p) h.vertices.insert(h.vertices.end(), {float(v.x), float(v.y), float(v.z)});
  std::vector<std::vector<int>> loops;
  for (int i = 0; i < n; ++i)
    for (int j = i + 1; j < n; ++j)
      for (int k = j + 1; k < n; ++k) {
        V nr = cross(sub(p[j], p[i]), sub(p[k], p[i]));
        const double l = std::sqrt(dot(nr, nr));
        if (l < 1e-12) continue;
        nr = {nr.x / l, nr.y / l, nr.z / l};
        double d = dot(nr, p[i]);
        int above = 0, below = 0;
        for (const V& q : p) above += dot(nr, q) - d > eps, below += dot(nr, q) - d < -eps;
        if (above && below) continue;
        if (above) nr = {-nr.x, -nr.y, -nr.z}, d = -d;
        std::vector<int> loop;
        for (int m = 0; m < n; ++m)
          if (std::fabs(dot(nr, p[m]) - d) <= eps) loop.push_back(m);
        if (std::find(loops.begin(), loops.end(), loop) != loops.end()) continue;
        loops.push_back(loop);
        V c{0, 0, 0};
        for (int m : loop) c = {c.x + p[m].x, c.y + p[m].y, c.z + p[m].z};
        c = {c.x / loop.size(), c.y / loop.size(), c.z / loop.size()};
        const V e1 = sub(p[loop[0]], c), e2 = cross(nr, e1);
        std::vector<int> ordered = loop;
        std::sort(ordered.begin(), ordered.end(), [&](int a, int b) {
          return std::atan2(dot(sub(p[a], c), e2), dot(sub(p[a], c), e1)) <
                 std::atan2(dot(sub(p[b], c), e2), dot(sub(p[b], c), e1));
        });
        h.planes.insert(h.planes.end(), {float(nr.x), float(nr.y), float(nr.z), float(d)});
        for (size_t q = 0; q < ordered.size(); ++q) {
          const int a = ordered[q], b = ordered[(q + 1) % ordered.size()];
          h.face_vertices.push_back(a);
          if (a < b) h.edges.push_back(a), h.edges.push_back(b);
        }
        h.face_start.push_back(int32_t(h.face_vertices.size()));
      }
  return h;
}

Hull dodecahedron(double r) {
  const double phi = (1 + std::sqrt(5.0)) / 2, s = r / std::sqrt(3.0);
  std::vector<V> p;
  for (int i = 0; i < 8; ++i) p.push_back({i & 1 ? s : -s, i & 2 ? s : -s, i & 4 ? s : -s});
  for (int i = 0; i < 4; ++i) {
    const double a = (i & 1 ? s : -s) / phi, b = (i & 2 ? s : -s) * phi;
    p.push_back({0, a, b}), p.push_back({a, b, 0}), p.push_back({b, 0, a});
  }
  return hull_from_points(p, 1e-6);
}

Hull random_hull(int count, uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> g;
  std::vector<V> p;
  for (int i = 0; i < count; ++i) {
    V v{g(rng), g(rng), g(rng)};
    const double l = std::sqrt(dot(v, v));
    p.push_back({0.5 * v.x / l, 0.4 * v.y / l, 0.3 * v.z / l});
  }
  return hull_from_points(p, 1e-9);
}

ShapeView box(float hx, float hy, float hz) {
  ShapeView s;
  s.type = ShapeType::box;
  s.half_extents[0] = hx, s.half_extents[1] = hy, s.half_extents[2] = hz;
  return s;
}
ShapeView sphere(float r) {
  ShapeView s;
  s.type = ShapeType::sphere, s.radius = r;
  return s;
}
ShapeView ground() {
  ShapeView s;
  s.type = ShapeType::plane;
  return s;
}

Pose pose(double x, double y, double z, double angle = 0, V axis = {0, 0, 1}) {
  const double l = std::sqrt(dot(axis, axis)), s = std::sin(angle / 2) / l;
  Pose p;
  p.position[0] = float(x), p.position[1] = float(y), p.position[2] = float(z);
  p.orientation[0] = float(std::cos(angle / 2));
  p.orientation[1] = float(axis.x * s), p.orientation[2] = float(axis.y * s), p.orientation[3] = float(axis.z * s);
  return p;
}

constexpr int kVariants = 64;
constexpr float kMargin = 0.01f;

/// Runs collide over kVariants pose pairs, one pair per iteration.
void run_pairs(benchmark::State& state, const ShapeView& a, const std::vector<Pose>& pa, const ShapeView& b,
               const std::vector<Pose>& pb) {
  ContactPoint out[kMaxManifoldPoints];
  int64_t contacts = 0;
  size_t i = 0;
  for (auto _ : state) {
    const int n = collide(a, pa[i], b, pb[i], kMargin, out);
    benchmark::DoNotOptimize(out);
    contacts += n;
    i = i + 1 == pa.size() ? 0 : i + 1;
  }
  state.SetItemsProcessed(state.iterations());
  state.counters["contacts/pair"] = double(contacts) / double(state.iterations());
}

void BM_BoxBoxResting(benchmark::State& state) {
  // A 0.5 m cube resting 2 mm deep on a wider box, small yaw and tilt: 4-point manifolds.
  std::vector<Pose> pa, pb;
  for (int k = 0; k < kVariants; ++k) {
    pa.push_back(pose(0, 0, 0));
    pb.push_back(pose(0.01 * (k % 7), -0.01 * (k % 5), 0.5 + 0.25 - 0.002, 0.3 + 0.01 * k, {0.01 * (k % 3), 0.01, 1}));
  }
  run_pairs(state, box(1, 1, 0.5f), pa, box(0.25f, 0.25f, 0.25f), pb);
}
BENCHMARK(BM_BoxBoxResting);

void BM_BoxPlane(benchmark::State& state) {
  std::vector<Pose> pa, pb;
  for (int k = 0; k < kVariants; ++k) {
    pa.push_back(pose(0.1 * k, 0, 0.25 - 0.002, 0.05 * k, {0.002 * (k % 4), 0.002, 1}));
    pb.push_back(Pose{});
  }
  run_pairs(state, box(0.25f, 0.25f, 0.25f), pa, ground(), pb);
}
BENCHMARK(BM_BoxPlane);

void BM_SphereSphere(benchmark::State& state) {
  std::vector<Pose> pa, pb;
  for (int k = 0; k < kVariants; ++k) {
    pa.push_back(pose(0, 0, 0));
    pb.push_back(pose(0.95 * std::cos(0.1 * k), 0.95 * std::sin(0.1 * k), 0.001 * k));
  }
  run_pairs(state, sphere(0.5f), pa, sphere(0.5f), pb);
}
BENCHMARK(BM_SphereSphere);

Pose rotated(Pose p, double qw, double qx, double qy, double qz) {
  // p.orientation <- q * p.orientation
  const double w = p.orientation[0], x = p.orientation[1], y = p.orientation[2], z = p.orientation[3];
  p.orientation[0] = float(qw * w - qx * x - qy * y - qz * z);
  p.orientation[1] = float(qw * x + qx * w + qy * z - qz * y);
  p.orientation[2] = float(qw * y - qx * z + qy * w + qz * x);
  p.orientation[3] = float(qw * z + qx * y - qy * x + qz * w);
  return p;
}

void BM_HullHullDodecahedronResting(benchmark::State& state) {
  // Two 20-vertex dodecahedra (pentagon faces) stacked face on face, 1-3 mm deep, turned and
  // tilted a little: both turned so that face 0 points down.
  const Hull h = dodecahedron(0.5);
  const V n0{h.planes[0], h.planes[1], h.planes[2]}, down{0, 0, -1};
  const V axis = cross(n0, down);
  const double angle = std::acos(std::max(-1.0, std::min(1.0, dot(n0, down))));
  const double inradius = h.planes[3];
  std::vector<Pose> pa, pb;
  for (int k = 0; k < kVariants; ++k) {
    pa.push_back(pose(0, 0, 0, angle, axis));
    const double yaw = 0.05 * k, tilt = 0.002 * (k % 5);
    Pose b = rotated(pose(0.03 * (k % 5), 0.02 * (k % 3), 2 * inradius - 0.001 * (1 + k % 3), angle, axis),
                     std::cos(yaw / 2), 0, 0, std::sin(yaw / 2));
    pb.push_back(rotated(b, std::cos(tilt / 2), std::sin(tilt / 2), 0, 0));
  }
  // Face 0 of a points down; its opposite face (up) carries b's face 0 (down).
  run_pairs(state, h.shape(), pa, h.shape(), pb);
}
BENCHMARK(BM_HullHullDodecahedronResting);

void BM_HullHullRandom20(benchmark::State& state) {
  // Two triangulated 20-vertex hulls in random orientations, 3 mm past first touch along a
  // random direction (found by bisection with collide itself): face, edge and vertex contacts.
  const Hull h = random_hull(20, 3);
  const ShapeView s = h.shape();
  std::mt19937 rng(5);
  std::normal_distribution<double> g;
  std::vector<Pose> pa, pb;
  for (int k = 0; k < kVariants; ++k) {
    V axis{g(rng), g(rng), g(rng)}, dir{g(rng), g(rng), g(rng)}, axis2{g(rng), g(rng), g(rng)};
    const double l = std::sqrt(dot(dir, dir));
    dir = {dir.x / l, dir.y / l, dir.z / l};
    const Pose a = pose(0, 0, 0, 3.0 * std::fabs(g(rng)), axis);
    Pose b = pose(0, 0, 0, 3.0 * std::fabs(g(rng)), axis2);
    double lo = 0, hi = 2;
    ContactPoint out[kMaxManifoldPoints];
    for (int i = 0; i < 40; ++i) {
      const double mid = 0.5 * (lo + hi);
      b.position[0] = float(dir.x * mid), b.position[1] = float(dir.y * mid), b.position[2] = float(dir.z * mid);
      (collide(s, a, s, b, 0.0f, out) > 0 ? lo : hi) = mid;
    }
    const double t = lo - 0.003;
    b.position[0] = float(dir.x * t), b.position[1] = float(dir.y * t), b.position[2] = float(dir.z * t);
    pa.push_back(a), pb.push_back(b);
  }
  run_pairs(state, s, pa, s, pb);
}
BENCHMARK(BM_HullHullRandom20);

void BM_CapsuleBoxLyingFlat(benchmark::State& state) {
  // A capsule lying on a box, 2 mm deep, turning about the vertical: 2-point contacts.
  ShapeView c;
  c.type = ShapeType::capsule, c.radius = 0.1f, c.half_height = 0.4f;
  std::vector<Pose> pa, pb;
  for (int k = 0; k < kVariants; ++k) {
    pa.push_back(rotated(pose(0.01 * (k % 5), 0, 0.5 + 0.1 - 0.002, 1.5707963, {0, 1, 0}), std::cos(0.05 * k),
                         0, 0, std::sin(0.05 * k)));
    pb.push_back(pose(0, 0, 0));
  }
  run_pairs(state, c, pa, box(1, 1, 0.5f), pb);
}
BENCHMARK(BM_CapsuleBoxLyingFlat);

void BM_BatchBoxBox1000(benchmark::State& state) {
  // 1000 box pairs on a grid, each a small cube resting on a larger one (2000 bodies).
  std::vector<ShapeView> shapes;
  std::vector<Pose> poses;
  std::vector<NarrowPair> pairs;
  for (int k = 0; k < 1000; ++k) {
    const double x = 3.0 * (k % 32), y = 3.0 * (k / 32);
    pairs.push_back({int32_t(shapes.size()), int32_t(shapes.size() + 1)});
    shapes.push_back(box(1, 1, 0.5f)), poses.push_back(pose(x, y, 0));
    shapes.push_back(box(0.25f, 0.25f, 0.25f));
    poses.push_back(pose(x + 0.01 * (k % 7), y, 0.75 - 0.002, 0.01 * k, {0.01 * (k % 3), 0.01, 1}));
  }
  std::vector<ContactPoint> out(4 * pairs.size());
  std::vector<int32_t> pair_of(out.size());
  int n = 0;
  for (auto _ : state) {
    n = collide_batch(shapes.data(), poses.data(), pairs.data(), int(pairs.size()), kMargin, out.data(), pair_of.data(),
                      int(out.size()));
    benchmark::DoNotOptimize(out.data());
  }
  state.SetItemsProcessed(state.iterations() * int64_t(pairs.size()));
  state.counters["contacts/pair"] = double(n) / double(pairs.size());
}
BENCHMARK(BM_BatchBoxBox1000);

}  // namespace
