// World queries between steps (runtime/ppe/world_queries.cpp): ray casts, overlap tests and
// shape sweeps.
//  - Each shape's ray cast against closed forms (a sphere at a known distance, a box face, a
//    capsule's side and cap, a hull's slanted face, a plane) and, on random shapes, against the
//    narrow phase: a tiny ball just before the hit is clear of the shape, one just after is in.
//  - The GJK overlap test against the narrow phase on random pairs; the sweeps against closed
//    forms and against the narrow phase (clear before the hit, touching at it).
//  - The world's queries, which walk the query tree, against brute force (every body with the
//    same exact test) on random worlds of mixed shapes, scales and orientations, with static,
//    sleeping and awake bodies and planes, over several seeds and sizes, after steps (refit),
//    moves, and adds and removes (rebuild).
//  - Queries leave the state hash and the following steps unchanged; bad input is refused.
#include <gtest/gtest.h>

#include <algorithm>
#include <functional>
#include <cmath>
#include <limits>
#include <optional>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "runtime/ppe/shape_distance.h"
#include "runtime/ppe/shape_ray.h"
#include "runtime/ppe/shape_sweep.h"
#include "runtime/ppe/world.h"
#include "runtime/spu/narrow_phase.h"
#include "testing/scenes.h"

namespace {

using namespace cellphys;
using namespace cellphys::ppe;
using cellphys::testing::ground_plane;

constexpr double kPi = 3.14159265358979323846;
constexpr float kInf = std::numeric_limits<float>::infinity();

struct Rng {
  std::mt19937 g;
  explicit Rng(uint32_t seed) : g(seed) {}
  double uniform(double lo, double hi) { return lo + (hi - lo) * (double(g()) / 4294967296.0); }
  Vec3d unit() {
    for (;;) {
      const Vec3d v{uniform(-1, 1), uniform(-1, 1), uniform(-1, 1)};
      const double n = norm(v);
      if (n > 0.1 && n <= 1.0) return v * (1.0 / n);
    }
  }
  void quaternion(float q[4]) {
    const Vec3d a = unit();
    const double angle = uniform(0, kPi);
    q[0] = float(std::cos(angle / 2));
    for (int k = 0; k < 3; ++k) q[k + 1] = float(std::sin(angle / 2) * a[k]);
  }
};

void axis_angle(const double axis[3], double angle, float q[4]) {
  q[0] = float(std::cos(angle / 2));
  for (int k = 0; k < 3; ++k) q[k + 1] = float(std::sin(angle / 2) * axis[k]);
}

// The float arguments a query was given, as the world reads them. Not inlined: GCC 12.2's SLP
// vectorizer (-O2 and up, AVX-512) forwards the doubles a local float array was filled from
// past their rounding when the array is read back in the same function.
__attribute__((noinline)) Vec3d loaded(const float* p) { return Vec3d::load(p); }

// q scaled to unit length as the world scales a query's orientation (not inlined, as above).
__attribute__((noinline)) void unit_quaternion(const float q[4], float out[4]) {
  const double l = std::sqrt(double(q[0]) * q[0] + double(q[1]) * q[1] + double(q[2]) * q[2] + double(q[3]) * q[3]);
  for (int k = 0; k < 4; ++k) out[k] = float(q[k] / l);
}

spu::Pose pose_at(const float p[3], const float q[4] = nullptr, float scale = 1.0f) {
  spu::Pose pose;
  std::copy(p, p + 3, pose.position);
  if (q) std::copy(q, q + 4, pose.orientation);
  pose.scale = scale;
  return pose;
}

spu::Pose body_pose(const World& w, BodyId id) {
  const BodyState s = w.state(id);
  return pose_at(s.position, s.orientation, w.scale(id));
}

// A random shape in a dictionary: sphere, capsule, box or hull, about 0.2..0.6 m.
uint32_t random_shape(ShapeDictionary& d, Rng& r, int kind) {
  switch (kind) {
    case 0: return d.add_sphere(float(r.uniform(0.2, 0.6)));
    case 1: return d.add_capsule(float(r.uniform(0.15, 0.4)), float(r.uniform(0.2, 0.6)));
    case 2: {
      const float h[3] = {float(r.uniform(0.15, 0.6)), float(r.uniform(0.15, 0.6)), float(r.uniform(0.15, 0.6))};
      return d.add_box(h);
    }
    default: {
      float pts[3 * 14];
      for (float& x : pts) x = float(r.uniform(-0.6, 0.6));
      return d.add_hull(pts, 14);
    }
  }
}

// ---- the narrow phase as an oracle ----------------------------------------------------------

// Deepest penetration the narrow phase finds between two shapes (-inf when it reports none).
double narrow_depth(const spu::ShapeView& a, const spu::Pose& pa, const spu::ShapeView& b, const spu::Pose& pb,
                    float margin) {
  spu::ContactPoint cp[spu::kMaxManifoldPoints];
  const int n = spu::collide(a, pa, b, pb, margin, cp);
  double depth = -std::numeric_limits<double>::infinity();
  for (int i = 0; i < n; ++i) depth = std::max(depth, double(cp[i].penetration));
  return depth;
}

spu::ShapeView ball_view(float r) {
  spu::ShapeView v;
  v.type = spu::ShapeType::sphere;
  v.radius = r;
  return v;
}

// ---- rays against one shape ---------------------------------------------------------------

TEST(ShapeRay, SphereAtAKnownDistance) {
  ShapeDictionary d;
  const spu::ShapeView& v = d.view(d.add_sphere(0.5f));
  const float p[3] = {5, 0, 0};
  ShapeRayHit h;
  ASSERT_TRUE(ray_shape(v, pose_at(p, nullptr, 2.0f), {0, 0, 0}, {1, 0, 0}, 100, h));
  EXPECT_DOUBLE_EQ(h.distance, 4.0);  // 5 - 0.5 * 2
  EXPECT_NEAR(h.normal.x, -1.0, 1e-15);
  EXPECT_NEAR(h.point.x, 4.0, 1e-15);
  // Off centre by 0.6 of the radius: the chord's near end, sqrt(1 - 0.36) radii before the centre.
  ASSERT_TRUE(ray_shape(v, pose_at(p, nullptr, 2.0f), {0, 0.6, 0}, {1, 0, 0}, 100, h));
  EXPECT_NEAR(h.distance, 5.0 - 0.8, 1e-12);
  EXPECT_NEAR(h.normal.y, 0.6, 1e-12);
  EXPECT_FALSE(ray_shape(v, pose_at(p, nullptr, 2.0f), {0, 0, 0}, {1, 0, 0}, 3.9, h));  // short of it
  EXPECT_FALSE(ray_shape(v, pose_at(p, nullptr, 2.0f), {0, 0, 0}, {-1, 0, 0}, 100, h));  // away from it
  EXPECT_FALSE(ray_shape(v, pose_at(p, nullptr, 2.0f), {0, 1.01, 0}, {1, 0, 0}, 100, h));  // passes by
}

TEST(ShapeRay, BoxFaceNormalRotatedAndScaled) {
  ShapeDictionary d;
  const float half[3] = {1, 2, 3};
  const spu::ShapeView& v = d.view(d.add_box(half));
  const double z[3] = {0, 0, 1};
  float q[4];
  axis_angle(z, kPi / 2, q);  // body x along world y
  const float p[3] = {0, 10, 0};
  ShapeRayHit h;
  ASSERT_TRUE(ray_shape(v, pose_at(p, q, 0.5f), {0, 0, 0}, {0, 1, 0}, 100, h));
  EXPECT_NEAR(h.distance, 9.5, 1e-12);  // half extent 1 (body x) at scale 0.5
  EXPECT_NEAR(h.normal.y, -1.0, 1e-12);
  EXPECT_NEAR(std::fabs(h.normal.x) + std::fabs(h.normal.z), 0.0, 1e-12);
  // From the side along world x: body y (half 2, scaled 1) faces it.
  ASSERT_TRUE(ray_shape(v, pose_at(p, q, 0.5f), {-5, 10.2, 0.3}, {1, 0, 0}, 100, h));
  EXPECT_NEAR(h.distance, 4.0, 1e-12);
  EXPECT_NEAR(h.normal.x, -1.0, 1e-12);
  // A slanted ray onto the top face (body z, half 3 at 0.5: z = 1.5) from above.
  const Vec3d dir = Vec3d{0.2, 0, -1} * (1.0 / std::sqrt(1.04));  // lands at x = 0.7, inside the half width 1
  ASSERT_TRUE(ray_shape(v, pose_at(p, q, 0.5f), {0, 10, 5}, dir, 100, h));
  EXPECT_NEAR(h.distance, 3.5 * std::sqrt(1.04), 1e-12);
  EXPECT_NEAR(h.normal.z, 1.0, 1e-12);
}

TEST(ShapeRay, CapsuleSideAndCap) {
  ShapeDictionary d;
  const spu::ShapeView& v = d.view(d.add_capsule(0.5f, 2.0f));
  const float p[3] = {3, 0, 0};
  ShapeRayHit h;
  ASSERT_TRUE(ray_shape(v, pose_at(p), {0, 0, 1}, {1, 0, 0}, 100, h));  // the side
  EXPECT_NEAR(h.distance, 2.5, 1e-12);
  EXPECT_NEAR(h.normal.x, -1.0, 1e-12);
  // Lying along x (turned about y), a ray down onto the cap 0.2 beyond the core's end.
  const double y[3] = {0, 1, 0};
  float q[4];
  axis_angle(y, kPi / 2, q);
  const float o[3] = {0, 0, 0};
  ASSERT_TRUE(ray_shape(v, pose_at(o, q), {2.2, 0, 5}, {0, 0, -1}, 100, h));
  const double height = std::sqrt(0.25 - 0.04);
  EXPECT_NEAR(h.distance, 5.0 - height, 1e-6);
  EXPECT_NEAR(h.normal.x, 0.2 / 0.5, 1e-6);
  EXPECT_NEAR(h.normal.z, height / 0.5, 1e-6);
  // Along the axis into the end cap: the tip at 2.5.
  ASSERT_TRUE(ray_shape(v, pose_at(o, q), {10, 0, 0}, {-1, 0, 0}, 100, h));
  EXPECT_NEAR(h.distance, 7.5, 1e-6);
  EXPECT_NEAR(h.normal.x, 1.0, 1e-6);
}

TEST(ShapeRay, HullSlantedFace) {
  // The octahedron |x| + |y| + |z| <= 1, scaled 2: the ray along -x at y = z = 0.1 meets the
  // face x + y + z = 2 at x = 1.8.
  ShapeDictionary d;
  const float pts[] = {1, 0, 0, -1, 0, 0, 0, 1, 0, 0, -1, 0, 0, 0, 1, 0, 0, -1};
  const spu::ShapeView& v = d.view(d.add_hull(pts, 6));
  const float o[3] = {0, 0, 0};
  ShapeRayHit h;
  ASSERT_TRUE(ray_shape(v, pose_at(o, nullptr, 2.0f), {5, 0.1, 0.1}, {-1, 0, 0}, 100, h));
  EXPECT_NEAR(h.distance, 3.2, 1e-6);
  const double s = 1.0 / std::sqrt(3.0);
  EXPECT_NEAR(h.normal.x, s, 1e-6);
  EXPECT_NEAR(h.normal.y, s, 1e-6);
  EXPECT_NEAR(h.normal.z, s, 1e-6);
  EXPECT_FALSE(ray_shape(v, pose_at(o, nullptr, 2.0f), {5, 1.5, 1.5}, {-1, 0, 0}, 100, h));  // past the edge
}

TEST(ShapeRay, PlaneAndStartingInside) {
  ShapeDictionary d;
  const float n[3] = {0, 0, 1};
  const spu::ShapeView& plane = d.view(d.add_plane(n, 0.0f));
  const float o[3] = {0, 0, 0};
  ShapeRayHit h;
  const Vec3d dir = Vec3d{1, 0, -1} * (1.0 / std::sqrt(2.0));
  ASSERT_TRUE(ray_shape(plane, pose_at(o), {0, 0, 5}, dir, 100, h));
  EXPECT_NEAR(h.distance, 5.0 * std::sqrt(2.0), 1e-12);
  EXPECT_NEAR(h.point.x, 5.0, 1e-12);
  EXPECT_NEAR(h.normal.z, 1.0, 1e-15);
  EXPECT_FALSE(ray_shape(plane, pose_at(o), {0, 0, 5}, {1, 0, 0}, 100, h));  // parallel
  // Inside: a hit at 0 with normal -dir, for every kind.
  ASSERT_TRUE(ray_shape(plane, pose_at(o), {0, 0, -1}, {0, 0, 1}, 100, h));
  EXPECT_EQ(h.distance, 0.0);
  EXPECT_EQ(h.normal.z, -1.0);
  Rng r(7);
  for (int kind = 0; kind < 4; ++kind) {
    const spu::ShapeView& v = d.view(random_shape(d, r, kind));
    ASSERT_TRUE(ray_shape(v, pose_at(o), {0.01, 0.02, 0.0}, {0, 1, 0}, 100, h)) << kind;
    EXPECT_EQ(h.distance, 0.0) << kind;
  }
}

// On random shapes, poses and rays: just before each hit a tiny ball is clear of the shape (the
// narrow phase finds no overlap), just after it is in; a ray that misses passes clear of it.
TEST(ShapeRay, RandomShapesAgainstTheNarrowPhase) {
  ShapeDictionary d;
  Rng r(11);
  const spu::ShapeView ball = ball_view(1e-6f);
  int hits = 0, misses = 0;
  for (int i = 0; i < 400; ++i) {
    const spu::ShapeView& v = d.view(random_shape(d, r, i % 4));
    float q[4], p[3] = {float(r.uniform(-1, 1)), float(r.uniform(-1, 1)), float(r.uniform(-1, 1))};
    r.quaternion(q);
    const spu::Pose pose = pose_at(p, q, float(r.uniform(0.5, 2.0)));
    // From 3 m out, aimed within 1 m of the centre.
    const Vec3d o = Vec3d::load(p) + r.unit() * 3.0;
    const Vec3d aim = Vec3d::load(p) + r.unit() * r.uniform(0, 1.0);
    const Vec3d dir = (aim - o) * (1.0 / norm(aim - o));
    ShapeRayHit h;
    if (ray_shape(v, pose, o, dir, 100, h)) {
      ++hits;
      ASSERT_GT(h.distance, 0.0);
      EXPECT_NEAR(norm(h.normal), 1.0, 1e-9);
      EXPECT_LT(dot(h.normal, dir), 1e-9) << "the ray enters against the normal";
      // A ball a fifth of the offset's depth below the surface; grazing rays (within 3 degrees
      // of the surface) are left out: their depth along the ray is too shallow to probe.
      const double across = -dot(h.normal, dir);
      if (across < 0.05) continue;
      const double step = 1e-3;
      const spu::ShapeView probe = ball_view(float(0.2 * step * across));
      const Vec3d before = o + dir * (h.distance - step), after = o + dir * (h.distance + step);
      float b[3] = {float(before.x), float(before.y), float(before.z)}, a[3] = {float(after.x), float(after.y), float(after.z)};
      EXPECT_LT(narrow_depth(probe, pose_at(b), v, pose, 0.0f), 0.0) << "shape " << i << " before its hit";
      EXPECT_GT(narrow_depth(probe, pose_at(a), v, pose, 0.0f), 0.0) << "shape " << i << " after its hit";
    } else {
      ++misses;
      for (int k = 0; k <= 120; ++k) {
        const Vec3d x = o + dir * (6.0 * k / 120);
        float xf[3] = {float(x.x), float(x.y), float(x.z)};
        ASSERT_LT(narrow_depth(ball, pose_at(xf), v, pose, 0.0f), 0.0) << "shape " << i << " missed at " << k;
      }
    }
  }
  EXPECT_GT(hits, 100);
  EXPECT_GT(misses, 20);
}

// ---- overlap and distance ----------------------------------------------------------------

TEST(ShapeDistance, ClosedForms) {
  ShapeDictionary d;
  const spu::ShapeView& s1 = d.view(d.add_sphere(0.5f));
  const float half[3] = {1, 1, 1};
  const spu::ShapeView& box = d.view(d.add_box(half));
  const float a[3] = {0, 0, 0}, b[3] = {3, 4, 0}, c[3] = {2, 2, 2};
  Separation s = separation(core_of(s1, pose_at(a)), core_of(s1, pose_at(b, nullptr, 2.0f)));
  EXPECT_FALSE(s.overlap);
  EXPECT_NEAR(s.distance, 5.0 - 1.5, 1e-12);
  EXPECT_NEAR(s.normal.x, 0.6, 1e-12);
  // A sphere at (2, 2, 2) off the unit box's corner: sqrt(3) - 0.5.
  s = separation(core_of(s1, pose_at(c)), core_of(box, pose_at(a)));
  EXPECT_NEAR(s.distance, std::sqrt(3.0) - 0.5, 1e-9);
  EXPECT_LE(s.lower, s.distance);
  EXPECT_GE(s.lower, s.distance - 1e-8);
  // Two boxes 0.5 apart face to face, one turned 45 degrees about x.
  const double x[3] = {1, 0, 0};
  float q[4];
  axis_angle(x, kPi / 4, q);
  const float e[3] = {2.5, 0, 0};
  s = separation(core_of(box, pose_at(a)), core_of(box, pose_at(e, q)));
  EXPECT_NEAR(s.distance, 0.5, 1e-9);
  const float f[3] = {1.9f, 0, 0};
  EXPECT_TRUE(separation(core_of(box, pose_at(a)), core_of(box, pose_at(f, q))).overlap);
}

// The GJK overlap test agrees with the narrow phase wherever the two are not within 1e-4 m of
// touching.
TEST(ShapeDistance, OverlapAgreesWithTheNarrowPhase) {
  ShapeDictionary d;
  Rng r(5);
  int overlapping = 0, apart = 0;
  for (int i = 0; i < 1500; ++i) {
    const spu::ShapeView& va = d.view(random_shape(d, r, i % 4));
    const spu::ShapeView& vb = d.view(random_shape(d, r, (i / 4) % 4));
    float qa[4], qb[4], pa[3] = {0, 0, 0}, pb[3];
    r.quaternion(qa), r.quaternion(qb);
    const Vec3d off = r.unit() * r.uniform(0.2, 1.8);
    for (int k = 0; k < 3; ++k) pb[k] = float(off[k]);
    const spu::Pose A = pose_at(pa, qa, float(r.uniform(0.6, 1.5))), B = pose_at(pb, qb, float(r.uniform(0.6, 1.5)));
    const bool gjk = shapes_overlap(va, A, vb, B);
    const double depth = narrow_depth(va, A, vb, B, 0.0f);
    const Separation s = separation(core_of(va, A), core_of(vb, B));
    if (depth > 1e-4) {
      EXPECT_TRUE(gjk) << "pair " << i << " narrow-phase depth " << depth;
      ++overlapping;
    }
    if (!s.overlap && s.distance > 1e-4) {
      EXPECT_FALSE(gjk);
      EXPECT_LE(depth, 0.0) << "pair " << i << " GJK distance " << s.distance;
      ++apart;
      // The closest points are on the two surfaces: the narrow phase puts a tiny ball at each
      // within 1e-6 of touching.
      const float a_pt[3] = {float(s.point_a.x), float(s.point_a.y), float(s.point_a.z)};
      const spu::ShapeView ball = ball_view(1e-6f);
      EXPECT_GT(narrow_depth(ball, pose_at(a_pt), va, A, 1e-5f), -1e-5) << "pair " << i;
    }
  }
  EXPECT_GT(overlapping, 200);
  EXPECT_GT(apart, 200);
}

// ---- sweeps ------------------------------------------------------------------------------

TEST(ShapeSweep, ClosedForms) {
  ShapeDictionary d;
  const spu::ShapeView& ball = d.view(d.add_sphere(0.5f));
  const spu::ShapeView& big = d.view(d.add_sphere(1.0f));
  const float half[3] = {1, 1, 1}, cube_half[3] = {0.5f, 0.5f, 0.5f};
  const spu::ShapeView& box = d.view(d.add_box(half));
  const spu::ShapeView& cube = d.view(d.add_box(cube_half));
  const spu::ShapeView& capsule = d.view(d.add_capsule(0.3f, 0.5f));
  const float n[3] = {0, 0, 1};
  const spu::ShapeView& ground = d.view(d.add_plane(n, 0.0f));
  const float o[3] = {0, 0, 0}, far[3] = {5, 0, 0};
  SweepHit h;
  // Sphere into sphere: at 5 - 1.5, never past it and within the tolerance.
  ASSERT_TRUE(sweep_shape(ball, pose_at(o), {1, 0, 0}, 10, big, pose_at(far), h));
  EXPECT_LE(h.distance, 3.5);
  EXPECT_GE(h.distance, 3.5 - kSweepTolerance);
  EXPECT_NEAR(h.normal.x, -1.0, 1e-6);
  EXPECT_NEAR(h.point.x, 4.0, 1e-5);
  // Sphere into a box face.
  ASSERT_TRUE(sweep_shape(ball, pose_at(o), {1, 0, 0}, 10, box, pose_at(far), h));
  EXPECT_LE(h.distance, 3.5);
  EXPECT_GE(h.distance, 3.5 - kSweepTolerance);
  EXPECT_NEAR(h.normal.x, -1.0, 1e-6);
  EXPECT_FALSE(sweep_shape(ball, pose_at(o), {1, 0, 0}, 3.4, box, pose_at(far), h));  // short
  EXPECT_FALSE(sweep_shape(ball, pose_at(o), {0, 1, 0}, 10, box, pose_at(far), h));   // sideways
  // A cube turned 45 degrees about x dropped on the ground from z = 3: its edge leads by
  // 0.5 sqrt 2 (a closed form, exact).
  const double x[3] = {1, 0, 0};
  float q[4];
  axis_angle(x, kPi / 4, q);
  const float up[3] = {0, 0, 3};
  ASSERT_TRUE(sweep_shape(cube, pose_at(up, q), {0, 0, -1}, 10, ground, pose_at(o), h));
  EXPECT_NEAR(h.distance, 3.0 - 0.5 * std::sqrt(2.0), 1e-6);
  EXPECT_NEAR(h.normal.z, 1.0, 1e-15);
  // An upright capsule (reach 0.8 below its centre) down onto a box's top at z = 0.5.
  const float cap_at[3] = {0.3f, 0.2f, 2.0f}, box_at[3] = {0, 0, -0.5f};
  ASSERT_TRUE(sweep_shape(capsule, pose_at(cap_at), {0, 0, -1}, 10, box, pose_at(box_at), h));
  EXPECT_LE(h.distance, 0.7 + 1e-6);
  EXPECT_GE(h.distance, 0.7 - kSweepTolerance - 1e-6);
  EXPECT_NEAR(h.normal.z, 1.0, 1e-5);
  // The cube turned 45 degrees about z, moving along x into the box: its edge leads.
  const double z[3] = {0, 0, 1};
  axis_angle(z, kPi / 4, q);
  ASSERT_TRUE(sweep_shape(cube, pose_at(o, q), {1, 0, 0}, 10, box, pose_at(far), h));
  EXPECT_LE(h.distance, 4.0 - 0.5 * std::sqrt(2.0) + 1e-6);
  EXPECT_GE(h.distance, 4.0 - 0.5 * std::sqrt(2.0) - kSweepTolerance - 1e-6);
  // A box resting on another (touching) misses it when lifted, and hits it at 0 pressed down.
  const float on_top[3] = {0.2f, 0, 1.5f};
  EXPECT_FALSE(sweep_shape(cube, pose_at(on_top), {0, 0, 1}, 10, box, pose_at(o), h));
  EXPECT_FALSE(sweep_shape(cube, pose_at(on_top), {1, 0, 0}, 0.5, box, pose_at(o), h));  // slides along it
  ASSERT_TRUE(sweep_shape(cube, pose_at(on_top), {0, 0, -1}, 10, box, pose_at(o), h));
  EXPECT_LE(h.distance, 1e-6);
  // Starting inside: 0, with normal -dir.
  ASSERT_TRUE(sweep_shape(ball, pose_at(far), {0, 1, 0}, 10, box, pose_at(far), h));
  EXPECT_EQ(h.distance, 0.0);
  EXPECT_EQ(h.normal.y, -1.0);
}

// Random sweeps of spheres, capsules and boxes against random shapes: the narrow phase finds
// the moving shape clear of the target all the way to 1 mm before the hit and touching (within
// twice the tolerance) at it; a sweep that misses stays clear all along.
TEST(ShapeSweep, RandomSweepsAgainstTheNarrowPhase) {
  ShapeDictionary d;
  Rng r(3);
  int hits = 0, misses = 0;
  for (int i = 0; i < 600; ++i) {
    const spu::ShapeView& mv = d.view(random_shape(d, r, i % 3));  // sphere, capsule, box
    const spu::ShapeView& tv = d.view(random_shape(d, r, (i / 3) % 4));
    float qm[4], qt[4], pt[3] = {0, 0, 0};
    r.quaternion(qm), r.quaternion(qt);
    const spu::Pose T = pose_at(pt, qt, float(r.uniform(0.6, 1.5)));
    const Vec3d start = r.unit() * 3.0, aim = r.unit() * r.uniform(0, 1.2);
    const Vec3d dir = (aim - start) * (1.0 / norm(aim - start));
    float ps[3] = {float(start.x), float(start.y), float(start.z)};
    const spu::Pose S = pose_at(ps, qm, float(r.uniform(0.6, 1.5)));
    auto moved = [&](double t) {
      spu::Pose p = S;
      for (int k = 0; k < 3; ++k) p.position[k] = float(start[k] + dir[k] * t);
      return p;
    };
    if (narrow_depth(mv, S, tv, T, 0.0f) > 0.0) continue;  // starts overlapping
    SweepHit h;
    const double max_dist = 6.0;
    if (sweep_shape(mv, S, dir, max_dist, tv, T, h)) {
      ++hits;
      for (int k = 0; k <= 40; ++k) {
        const double t = (h.distance - 1e-3) * k / 40;
        if (t < 0) break;
        EXPECT_LE(narrow_depth(mv, moved(t), tv, T, 0.0f), 1e-6) << "sweep " << i << " overlaps at " << t << " before " << h.distance;
      }
      EXPECT_GT(narrow_depth(mv, moved(h.distance), tv, T, float(2 * kSweepTolerance + 1e-5)), -2 * kSweepTolerance - 1e-5)
          << "sweep " << i << " not touching at its hit " << h.distance;
      EXPECT_NEAR(norm(h.normal), 1.0, 1e-9);
    } else {
      ++misses;
      for (int k = 0; k <= 120; ++k)
        EXPECT_LE(narrow_depth(mv, moved(max_dist * k / 120), tv, T, 0.0f), 1e-6) << "sweep " << i << " missed at " << k;
    }
  }
  EXPECT_GT(hits, 150);
  EXPECT_GT(misses, 50);
}

// ---- the world against brute force -------------------------------------------------------

// A random world of n bodies of every kind, scale and orientation on a jittered 4 m grid
// (apart), 15% static, with a ground plane below and a slanted plane beyond a corner, in zero
// gravity; stepped until asleep, then some woken.
struct RandomWorld {
  std::unique_ptr<World> w;
  float size = 0;  // the grid's side (m)
  std::vector<BodyId> dynamic;

  RandomWorld(int n, uint32_t seed) {
    WorldSettings s;
    for (float& g : s.globals.gravity) g = 0.0f;
    w = std::make_unique<World>(s);
    Rng r(seed);
    std::vector<uint32_t> shapes;
    for (int i = 0; i < 24; ++i) shapes.push_back(random_shape(w->shapes(), r, i % 4));
    const float ground_n[3] = {0, 0, 1}, slant_n[3] = {1, 1, 1};
    const int k = int(std::ceil(std::cbrt(double(n))));
    size = 4.0f * k;
    BodyDesc plane;
    plane.shape = w->shapes().add_plane(ground_n, -3.0f);
    w->add_body(plane);
    plane.shape = w->shapes().add_plane(slant_n, -3.0f);
    w->add_body(plane);
    for (int i = 0; i < n; ++i) {
      BodyDesc b;
      b.shape = shapes[r.g() % shapes.size()];
      b.scale = float(r.uniform(0.6, 1.4));
      b.density = 500.0f;
      b.is_static = r.uniform(0, 1) < 0.15;
      r.quaternion(b.state.orientation);
      const int cell[3] = {i % k, (i / k) % k, i / (k * k)};
      for (int a = 0; a < 3; ++a) b.state.position[a] = float(4.0 * cell[a] + r.uniform(-0.3, 0.3));
      const BodyId id = w->add_body(b);
      if (!b.is_static) dynamic.push_back(id);
    }
    for (int i = 0; i < 40; ++i) w->step();  // all asleep after 0.5 s at rest
    for (size_t i = 0; i < dynamic.size(); i += 3) {  // a third woken, drifting slowly
      BodyState st = w->state(dynamic[i]);
      st.velocity[0] = float(r.uniform(-3, 3));
      st.angular_velocity[2] = float(r.uniform(-1, 1));
      w->set_state(dynamic[i], st);
    }
  }
};

struct Brute {
  const World& w;
  bool passes(BodyId id, const QueryFilter& f) const {
    if (w.is_static(id) ? !f.static_bodies : (w.is_awake(id) ? !f.awake_bodies : !f.sleeping_bodies)) return false;
    return !f.accept || f.accept(id);
  }
  std::vector<std::pair<double, BodyId>> rays(const Vec3d& o, const Vec3d& d, double max_dist, const QueryFilter& f) const {
    std::vector<std::pair<double, BodyId>> out;
    for (BodyId id : w.bodies()) {
      ShapeRayHit h;
      if (passes(id, f) && ray_shape(w.shapes().view(w.shape(id)), body_pose(w, id), o, d, max_dist, h))
        out.emplace_back(h.distance, id);
    }
    std::sort(out.begin(), out.end());
    return out;
  }
  std::vector<BodyId> overlaps(const spu::ShapeView& q, const spu::Pose& p, const QueryFilter& f) const {
    std::vector<BodyId> out;
    for (BodyId id : w.bodies())
      if (passes(id, f) && shapes_overlap(q, p, w.shapes().view(w.shape(id)), body_pose(w, id))) out.push_back(id);
    return out;
  }
  std::optional<std::pair<double, BodyId>> sweep(const spu::ShapeView& q, const spu::Pose& p, const Vec3d& d,
                                                 double max_dist, const QueryFilter& f) const {
    std::optional<std::pair<double, BodyId>> best;
    for (BodyId id : w.bodies()) {
      SweepHit h;
      if (passes(id, f) && sweep_shape(q, p, d, max_dist, w.shapes().view(w.shape(id)), body_pose(w, id), h))
        if (!best || std::make_pair(h.distance, id) < *best) best = std::make_pair(h.distance, id);
    }
    return best;
  }
};

struct Counts {
  int ray_hits = 0, overlaps = 0, sweep_hits = 0, statics = 0, asleep = 0, awake = 0, planes = 0;
};

// `rays` random rays, half aimed at a body, and as many overlap and sweep queries, each with
// one of four filters: the world's answers equal brute force's.
void check_against_brute_force(World& w, float size, uint32_t seed, int rays, Counts& c) {
  Rng r(seed);
  const Brute brute{w};
  const std::vector<BodyId> ids = w.bodies();
  const BodyId odd_one = ids[ids.size() / 2];
  std::vector<QueryFilter> filters(4);
  filters[1].static_bodies = false;
  filters[2].sleeping_bodies = false, filters[2].awake_bodies = true;
  filters[3].accept = [odd_one](BodyId id) { return id % 5 != 0 && id != odd_one; };
  auto tally = [&](BodyId id) {
    if (w.shapes().type(w.shape(id)) == spu::ShapeType::plane) ++c.planes;
    else if (w.is_static(id)) ++c.statics;
    else if (w.is_awake(id)) ++c.awake;
    else ++c.asleep;
  };
  for (int i = 0; i < rays; ++i) {
    const QueryFilter& f = filters[i % 4];
    const Vec3d o{r.uniform(-4, size + 2), r.uniform(-4, size + 2), r.uniform(-4, size + 2)};
    Vec3d d = r.unit();
    if (i % 2) {
      const BodyState s = w.state(ids[r.g() % ids.size()]);
      d = Vec3d::load(s.position) + r.unit() * 0.3 - o;
      d = d * (1.0 / norm(d));
    }
    const float of[3] = {float(o.x), float(o.y), float(o.z)}, df[3] = {float(d.x), float(d.y), float(d.z)};
    const Vec3d od = loaded(of), dd = loaded(df) * (1.0 / norm(loaded(df)));
    const float max_dist = i % 7 == 0 ? kInf : float(r.uniform(1.0, 2.0 * size));
    const auto expected = brute.rays(od, dd, max_dist, f);
    const std::optional<QueryHit> first = w.ray_cast(of, df, max_dist, f);
    ASSERT_EQ(first.has_value(), !expected.empty()) << "ray " << i;
    if (first) {
      EXPECT_EQ(first->body, expected[0].second) << "ray " << i;
      EXPECT_EQ(first->distance, float(expected[0].first)) << "ray " << i;
      ++c.ray_hits;
      tally(first->body);
    }
    const std::vector<QueryHit> all = w.ray_cast_all(of, df, max_dist, f);
    ASSERT_EQ(all.size(), expected.size()) << "ray " << i;
    for (size_t k = 0; k < all.size(); ++k) {
      EXPECT_EQ(all[k].body, expected[k].second) << "ray " << i << " hit " << k;
      EXPECT_EQ(all[k].distance, float(expected[k].first)) << "ray " << i << " hit " << k;
    }

    // Overlaps: a sphere or a turned box about a body or anywhere.
    const float centre[3] = {float(o.x), float(o.y), float(o.z)};
    if (i % 2 == 0) {
      const float radius = float(r.uniform(0.2, 4.0));
      const std::vector<BodyId> got = w.overlap_sphere(centre, radius, f);
      EXPECT_EQ(got, brute.overlaps(ball_view(radius), pose_at(centre), f)) << "sphere " << i;
      c.overlaps += int(got.size());
    } else {
      const float half[3] = {float(r.uniform(0.2, 3)), float(r.uniform(0.2, 3)), float(r.uniform(0.2, 3))};
      float q[4];
      r.quaternion(q);
      spu::ShapeView box;
      box.type = spu::ShapeType::box;
      std::copy(half, half + 3, box.half_extents);
      const std::vector<BodyId> got = w.overlap_box(centre, half, q, f);
      float qn[4];
      unit_quaternion(q, qn);
      EXPECT_EQ(got, brute.overlaps(box, pose_at(centre, qn), f)) << "box " << i;
      c.overlaps += int(got.size());
    }

    // A sweep of a sphere, capsule or box along the ray.
    if (i % 3 == 0 || rays <= 200) {
      QueryShape shape;
      spu::ShapeView view;
      if (i % 3 == 0) shape = QueryShape::sphere(float(r.uniform(0.1, 0.6)));
      if (i % 3 == 1) shape = QueryShape::capsule(float(r.uniform(0.1, 0.4)), float(r.uniform(0.1, 0.6)));
      if (i % 3 == 2) {
        const float half[3] = {float(r.uniform(0.1, 0.5)), float(r.uniform(0.1, 0.5)), float(r.uniform(0.1, 0.5))};
        shape = QueryShape::box(half);
      }
      view.type = shape.type, view.radius = shape.radius, view.half_height = shape.half_height;
      std::copy(shape.half_extents, shape.half_extents + 3, view.half_extents);
      float q[4];
      r.quaternion(q);
      float qn[4];
      unit_quaternion(q, qn);
      const auto expected_sweep = brute.sweep(view, pose_at(of, qn), dd, max_dist, f);
      const std::optional<QueryHit> got = w.shape_cast(shape, of, q, df, max_dist, f);
      ASSERT_EQ(got.has_value(), expected_sweep.has_value()) << "sweep " << i;
      if (got) {
        EXPECT_EQ(got->body, expected_sweep->second) << "sweep " << i;
        EXPECT_EQ(got->distance, float(expected_sweep->first)) << "sweep " << i;
        ++c.sweep_hits;
      }
    }
  }
}

class WorldQueries : public ::testing::TestWithParam<std::pair<int, uint32_t>> {};

TEST_P(WorldQueries, MatchBruteForce) {
  const auto [n, seed] = GetParam();
  RandomWorld rw(n, seed);
  World& w = *rw.w;
  const int rays = n >= 1000 ? 150 : 300;
  Counts c;
  check_against_brute_force(w, rw.size, seed * 17 + 1, rays, c);
  // After steps (the tree refitted, or rebuilt when it grew loose).
  for (int i = 0; i < 20; ++i) w.step();
  check_against_brute_force(w, rw.size, seed * 17 + 2, rays / 2, c);
  // A tenth of the bodies moved 1..3 m (the same bodies: the tree refitted).
  Rng r(seed);
  for (size_t i = 0; i < rw.dynamic.size(); i += 10) {
    BodyState s = w.state(rw.dynamic[i]);
    for (int k = 0; k < 3; ++k) s.position[k] += float(r.uniform(1, 3) * (r.uniform(0, 1) < 0.5 ? -1 : 1));
    w.set_state(rw.dynamic[i], s);
  }
  check_against_brute_force(w, rw.size, seed * 17 + 4, rays / 2, c);
  // Removed and added bodies (the tree rebuilt).
  w.remove_body(rw.dynamic[5]);
  w.remove_body(rw.dynamic[6]);
  BodyDesc b;
  b.shape = w.shape(rw.dynamic[7]);
  b.density = 500;
  b.state.position[0] = rw.size / 2, b.state.position[1] = rw.size / 2, b.state.position[2] = rw.size + 2;
  w.add_body(b);
  check_against_brute_force(w, rw.size, seed * 17 + 3, rays / 2, c);
  // Every kind of body was hit along the way.
  EXPECT_GT(c.ray_hits, rays / 2);
  EXPECT_GT(c.statics, 0);
  EXPECT_GT(c.asleep, 0);
  EXPECT_GT(c.awake, 0);
  EXPECT_GT(c.planes, 0);
  EXPECT_GT(c.overlaps, 0);
  EXPECT_GT(c.sweep_hits, 10);
}

INSTANTIATE_TEST_SUITE_P(SeedsAndSizes, WorldQueries,
                         ::testing::Values(std::make_pair(30, 1u), std::make_pair(200, 2u), std::make_pair(200, 3u),
                                           std::make_pair(1500, 4u)),
                         [](const auto& info) {
                           return std::to_string(info.param.first) + "_bodies_seed_" + std::to_string(info.param.second);
                         });

// ---- sleeping and static bodies, filters ---------------------------------------------------

TEST(WorldQueries, SleepingAndStaticBodiesAreHit) {
  World w;
  const BodyId ground = ground_plane(w);
  const float half[3] = {0.5f, 0.5f, 0.5f}, at[3] = {0, 0, 0.5f};
  const BodyId box = cellphys::testing::add_box(w, half, 1.0f, at);
  BodyDesc wall;
  wall.shape = w.shapes().add_box(half);
  wall.is_static = true;
  wall.state.position[0] = 3, wall.state.position[2] = 0.5f;
  const BodyId fixed = w.add_body(wall);
  for (int i = 0; i < 120 && w.is_awake(box); ++i) w.step();
  ASSERT_FALSE(w.is_awake(box)) << "the box should have gone to sleep";
  const float from_above[3] = {0.1f, 0.1f, 5}, down[3] = {0, 0, -1};
  std::optional<QueryHit> h = w.ray_cast(from_above, down, 10);
  ASSERT_TRUE(h);
  EXPECT_EQ(h->body, box);
  EXPECT_NEAR(h->distance, 5.0f - (w.state(box).position[2] + 0.5f), 1e-5f);  // its top, where it went to sleep
  EXPECT_NEAR(h->normal[2], 1.0f, 1e-4f);
  QueryFilter awake_only;
  awake_only.sleeping_bodies = false;
  h = w.ray_cast(from_above, down, 10, awake_only);
  ASSERT_TRUE(h);
  EXPECT_EQ(h->body, ground);  // through the sleeping box to the ground
  EXPECT_NEAR(h->distance, 5.0f, 1e-5f);
  std::vector<QueryHit> all = w.ray_cast_all(from_above, down, 10);
  ASSERT_EQ(all.size(), 2u);
  EXPECT_EQ(all[0].body, box);
  EXPECT_EQ(all[1].body, ground);
  const float side[3] = {-5, 0, 0.5f}, along_x[3] = {1, 0, 0};
  all = w.ray_cast_all(side, along_x, 100);
  ASSERT_EQ(all.size(), 2u);
  EXPECT_EQ(all[1].body, fixed);
  EXPECT_NEAR(all[1].distance, 7.5f, 1e-5f);
  QueryFilter no_statics;
  no_statics.static_bodies = false;
  all = w.ray_cast_all(side, along_x, 100, no_statics);
  ASSERT_EQ(all.size(), 1u);
  EXPECT_EQ(all[0].body, box);
  const float centre[3] = {1.5f, 0, 0.5f};
  EXPECT_EQ(w.overlap_sphere(centre, 1.05f), (std::vector<BodyId>{ground, box, fixed}));
  EXPECT_EQ(w.overlap_sphere(centre, 1.05f, no_statics), (std::vector<BodyId>{box}));
  const float q[4] = {1, 0, 0, 0}, thin[3] = {0.2f, 0.2f, 0.2f}, gap[3] = {1.5f, 0, 0.5f};
  EXPECT_TRUE(w.overlap_box(gap, thin, q).empty());
  // A sphere swept along x from the left meets the sleeping box, then the static one.
  const float start[3] = {-5, 0, 0.6f};
  const std::optional<QueryHit> s = w.shape_cast(QueryShape::sphere(0.25f), start, q, along_x, 100);
  ASSERT_TRUE(s);
  EXPECT_EQ(s->body, box);
  EXPECT_NEAR(s->distance, 4.25f, 1e-4f);
  QueryFilter not_the_box;
  not_the_box.accept = [box](BodyId id) { return id != box; };
  const std::optional<QueryHit> s2 = w.shape_cast(QueryShape::sphere(0.25f), start, q, along_x, 100, not_the_box);
  ASSERT_TRUE(s2);
  EXPECT_EQ(s2->body, fixed);
  EXPECT_NEAR(s2->distance, 7.25f, 1e-4f);
  // A sphere resting on the ground swept sideways misses the ground (it slides along it).
  const float resting[3] = {-3, 0, 0.25f};
  const std::optional<QueryHit> slide = w.shape_cast(QueryShape::sphere(0.25f), resting, q, along_x, 1.0f);
  EXPECT_FALSE(slide.has_value());
}

// ---- queries change nothing ------------------------------------------------------------------

TEST(WorldQueries, LeaveTheStateAndTheStepsUnchanged) {
  // Two worlds built alike; one is queried between its steps.
  World a, b;
  cellphys::testing::sparse_world(a, 200, 24.0f, 9);
  cellphys::testing::sparse_world(b, 200, 24.0f, 9);
  for (int i = 0; i < 10; ++i) a.step(), b.step();
  Rng r(2);
  for (int step = 0; step < 40; ++step) {
    const uint64_t before = a.state_hash();
    for (int i = 0; i < 50; ++i) {
      const float o[3] = {float(r.uniform(-12, 12)), float(r.uniform(-12, 12)), float(r.uniform(0, 3))};
      const Vec3d u = r.unit();
      const float d[3] = {float(u.x), float(u.y), float(u.z)}, q[4] = {1, 0, 0, 0}, half[3] = {1, 1, 1};
      a.ray_cast(o, d, 30);
      a.ray_cast_all(o, d, kInf);
      a.overlap_sphere(o, 1.5f);
      a.overlap_box(o, half, q);
      a.shape_cast(QueryShape::capsule(0.2f, 0.3f), o, q, d, 10);
    }
    ASSERT_EQ(a.state_hash(), before) << "step " << step;
    a.step();
    b.step();
    ASSERT_EQ(a.state_hash(), b.state_hash()) << "step " << step;
  }
}

// Queries of one world from two threads at once (the first after a step brings the tree up to
// date under a lock) give what one thread gets.
TEST(WorldQueries, ConcurrentQueriesAgree) {
  World w;
  cellphys::testing::sparse_world(w, 400, 30.0f, 4);
  for (int step = 0; step < 5; ++step) {
    w.step();
    std::vector<std::optional<QueryHit>> got[2];
    auto run = [&w](std::vector<std::optional<QueryHit>>& out) {
      Rng r(8);
      for (int i = 0; i < 300; ++i) {
        const float o[3] = {float(r.uniform(-15, 15)), float(r.uniform(-15, 15)), 2.0f};
        const Vec3d u = r.unit();
        const float d[3] = {float(u.x), float(u.y), float(u.z)};
        out.push_back(w.ray_cast(o, d, 40));
      }
    };
    std::thread t0(run, std::ref(got[0])), t1(run, std::ref(got[1]));
    t0.join(), t1.join();
    ASSERT_EQ(got[0].size(), got[1].size());
    for (size_t i = 0; i < got[0].size(); ++i) {
      ASSERT_EQ(got[0][i].has_value(), got[1][i].has_value());
      if (!got[0][i]) continue;
      EXPECT_EQ(got[0][i]->body, got[1][i]->body);
      EXPECT_EQ(got[0][i]->distance, got[1][i]->distance);
    }
  }
}

// ---- bad input ------------------------------------------------------------------------------

void expect_error(const std::function<void()>& f, const std::string& words) {
  try {
    f();
    ADD_FAILURE() << "no WorldError; expected one naming " << words;
  } catch (const WorldError& e) {
    EXPECT_NE(std::string(e.what()).find(words), std::string::npos) << e.what();
  }
}

TEST(WorldQueries, BadInputIsRefused) {
  World w;
  ground_plane(w);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float ok[3] = {0, 0, 1}, bad[3] = {nan, 0, 0}, zero[3] = {0, 0, 0}, q[4] = {1, 0, 0, 0}, q0[4] = {0, 0, 0, 0};
  const float half[3] = {1, 1, 1}, flat[3] = {1, 0, 1};
  const uint64_t hash = w.state_hash();
  expect_error([&] { w.ray_cast(bad, ok, 1); }, "ray_cast: origin is not finite");
  expect_error([&] { w.ray_cast(ok, zero, 1); }, "ray_cast: dir is zero");
  expect_error([&] { w.ray_cast(ok, bad, 1); }, "ray_cast: dir is not finite");
  expect_error([&] { w.ray_cast(ok, ok, -1); }, "ray_cast: max_dist must be >= 0");
  expect_error([&] { w.ray_cast(ok, ok, nan); }, "max_dist");
  expect_error([&] { w.ray_cast_all(bad, ok, 1); }, "ray_cast_all: origin");
  expect_error([&] { w.ray_cast_all(ok, zero, 1); }, "ray_cast_all: dir is zero");
  expect_error([&] { w.overlap_sphere(bad, 1); }, "overlap_sphere: centre is not finite");
  expect_error([&] { w.overlap_sphere(ok, 0); }, "overlap_sphere: radius must be positive");
  expect_error([&] { w.overlap_sphere(ok, -kInf); }, "radius");
  expect_error([&] { w.overlap_box(ok, flat, q); }, "overlap_box: half_extents y must be positive");
  expect_error([&] { w.overlap_box(ok, half, q0); }, "overlap_box: orientation is zero");
  expect_error([&] { w.shape_cast(QueryShape::sphere(0), ok, q, ok, 1); }, "shape_cast: shape radius");
  expect_error([&] { w.shape_cast(QueryShape::capsule(1, 0), ok, q, ok, 1); }, "shape_cast: shape half_height");
  expect_error([&] { w.shape_cast(QueryShape::sphere(1), bad, q, ok, 1); }, "shape_cast: position is not finite");
  expect_error([&] { w.shape_cast(QueryShape::sphere(1), ok, q, zero, 1); }, "shape_cast: dir is zero");
  expect_error([&] { w.shape_cast(QueryShape::sphere(1), ok, q, ok, -2); }, "shape_cast: max_dist");
  QueryShape plane;
  plane.type = spu::ShapeType::plane;
  expect_error([&] { w.shape_cast(plane, ok, q, ok, 1); }, "shape_cast: shape must be a sphere, capsule or box, got plane");
  EXPECT_EQ(w.state_hash(), hash);
  // A zero distance is allowed: only a ray starting in a body hits.
  const float below[3] = {0, 0, -1};
  EXPECT_FALSE(w.ray_cast(ok, ok, 0).has_value());
  EXPECT_TRUE(w.ray_cast(below, ok, 0).has_value());
}

}  // namespace
