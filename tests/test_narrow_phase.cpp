// Narrow phase against things we did not compute with it: closed forms for the primitive
// pairs and simple stackings, and for convex hulls a brute-force reference (every candidate
// axis evaluated with support functions, plus a dense sampling of directions). Hulls are made
// here by brute force from point sets (every supporting plane through three points), so the
// topology does not come from the code under test either.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstring>
#include <random>
#include <vector>

#include "runtime/spu/narrow_phase.h"

namespace {

using namespace cellphys::spu;
using Eigen::AngleAxisd;
using Eigen::Quaterniond;
using Eigen::Vector3d;

constexpr float kMargin = 0.01f;
const double kPi = std::acos(-1.0);

// ---- shapes and poses -----------------------------------------------------------------------

Pose pose_at(const Vector3d& p, const Quaterniond& q = Quaterniond::Identity(), float scale = 1.0f) {
  Pose pose;
  for (int i = 0; i < 3; ++i) pose.position[i] = float(p[i]);
  pose.orientation[0] = float(q.w()), pose.orientation[1] = float(q.x());
  pose.orientation[2] = float(q.y()), pose.orientation[3] = float(q.z());
  pose.scale = scale;
  return pose;
}
Quaterniond rot(double angle, const Vector3d& axis) { return Quaterniond(AngleAxisd(angle, axis.normalized())); }

ShapeView sphere(float r) {
  ShapeView s;
  s.type = ShapeType::sphere, s.radius = r;
  return s;
}
ShapeView capsule(float r, float hh) {
  ShapeView s;
  s.type = ShapeType::capsule, s.radius = r, s.half_height = hh;
  return s;
}
ShapeView box(float hx, float hy, float hz) {
  ShapeView s;
  s.type = ShapeType::box;
  s.half_extents[0] = hx, s.half_extents[1] = hy, s.half_extents[2] = hz;
  return s;
}
ShapeView plane(const Vector3d& n, float offset) {
  ShapeView s;
  s.type = ShapeType::plane;
  const Vector3d u = n.normalized();
  for (int i = 0; i < 3; ++i) s.normal[i] = float(u[i]);
  s.offset = offset;
  return s;
}

/// Owns the arrays of a HullView.
struct TestHull {
  std::vector<float> vertices, planes;
  std::vector<int32_t> face_start{0}, face_vertices, edges;

  ShapeView shape() const {
    ShapeView s;
    s.type = ShapeType::hull;
    s.hull.num_vertices = int32_t(vertices.size() / 3), s.hull.vertices = vertices.data();
    s.hull.num_faces = int32_t(planes.size() / 4), s.hull.planes = planes.data();
    s.hull.face_start = face_start.data(), s.hull.face_vertices = face_vertices.data();
    s.hull.num_edges = int32_t(edges.size() / 2), s.hull.edges = edges.data();
    return s;
  }
  Vector3d vertex(int i) const { return {vertices[3 * i], vertices[3 * i + 1], vertices[3 * i + 2]}; }
  int num_vertices() const { return int(vertices.size() / 3); }
};

/// Convex hull of points in convex position, by brute force: every plane through three points
/// with all points on one side is a face; points within eps (relative) of it are its loop,
/// sorted counter-clockwise about the outward normal. Points are rounded to float first.
TestHull hull_from_points(std::vector<Vector3d> pts, double eps = 1e-9) {
  for (auto& p : pts) p = p.cast<float>().cast<double>();
  double scale = 0.0;
  for (const auto& p : pts) scale = std::max(scale, p.norm());
  const int n = int(pts.size());
  struct Face {
    Vector3d n;
    double d;
    std::vector<int> loop;
  };
  std::vector<Face> faces;
  for (int i = 0; i < n; ++i)
    for (int j = i + 1; j < n; ++j)
      for (int k = j + 1; k < n; ++k) {
        Vector3d nrm = (pts[j] - pts[i]).cross(pts[k] - pts[i]);
        if (nrm.norm() < 1e-9 * scale * scale) continue;
        nrm.normalize();
        double d = nrm.dot(pts[i]);
        int above = 0, below = 0;
        for (const auto& p : pts) {
          const double s = nrm.dot(p) - d;
          above += s > eps * scale, below += s < -eps * scale;
        }
        if (above && below) continue;
        if (above) nrm = -nrm, d = -d;
        Face f{nrm, d, {}};
        for (int m = 0; m < n; ++m)
          if (std::fabs(nrm.dot(pts[m]) - d) <= eps * scale) f.loop.push_back(m);
        bool dup = false;  // the same face found from another triple of its points
        for (const auto& g : faces) dup |= std::is_permutation(g.loop.begin(), g.loop.end(), f.loop.begin(), f.loop.end());
        if (dup) continue;
        Vector3d c = Vector3d::Zero();
        for (int m : f.loop) c += pts[m];
        c /= double(f.loop.size());
        const Vector3d e1 = (pts[f.loop[0]] - c).normalized(), e2 = nrm.cross(e1);
        std::sort(f.loop.begin(), f.loop.end(), [&](int a, int b) {
          return std::atan2((pts[a] - c).dot(e2), (pts[a] - c).dot(e1)) <
                 std::atan2((pts[b] - c).dot(e2), (pts[b] - c).dot(e1));
        });
        faces.push_back(f);
      }
  std::vector<int> remap(n, -1);
  TestHull h;
  for (const auto& f : faces)
    for (int m : f.loop)
      if (remap[m] < 0) {
        remap[m] = h.num_vertices();
        for (int c = 0; c < 3; ++c) h.vertices.push_back(float(pts[m][c]));
      }
  for (const auto& f : faces) {
    for (int c = 0; c < 3; ++c) h.planes.push_back(float(f.n[c]));
    h.planes.push_back(float(f.d));
    for (size_t k = 0; k < f.loop.size(); ++k) {
      const int a = remap[f.loop[k]], b = remap[f.loop[(k + 1) % f.loop.size()]];
      h.face_vertices.push_back(a);
      if (a < b) h.edges.push_back(a), h.edges.push_back(b);  // the twin b->a is on the other face
    }
    h.face_start.push_back(int32_t(h.face_vertices.size()));
  }
  return h;
}

/// A box as a hand-written hull, numbered differently from the engine's own box.
TestHull box_hull(float hx, float hy, float hz) {
  TestHull h;
  const int sx[8] = {-1, 1, 1, -1, -1, 1, 1, -1}, sy[8] = {-1, -1, 1, 1, -1, -1, 1, 1};
  const int sz[8] = {-1, -1, -1, -1, 1, 1, 1, 1};
  for (int i = 0; i < 8; ++i) h.vertices.insert(h.vertices.end(), {sx[i] * hx, sy[i] * hy, sz[i] * hz});
  h.planes = {0, 0, -1, hz, 0, 0, 1, hz, 0, -1, 0, hy, 1, 0, 0, hx, 0, 1, 0, hy, -1, 0, 0, hx};
  h.face_vertices = {0, 3, 2, 1, 4, 5, 6, 7, 0, 1, 5, 4, 1, 2, 6, 5, 2, 3, 7, 6, 3, 0, 4, 7};
  h.face_start = {0, 4, 8, 12, 16, 20, 24};
  h.edges = {0, 1, 1, 2, 2, 3, 3, 0, 4, 5, 5, 6, 6, 7, 7, 4, 0, 4, 1, 5, 2, 6, 3, 7};
  return h;
}

/// A regular-ish tetrahedron written by hand: apex up, base triangle at z = -h/3.
TestHull tetrahedron(float a) {
  TestHull h;
  const Vector3d p[4] = {{a, 0, -a / 3}, {-a / 2, a * 0.8660254, -a / 3}, {-a / 2, -a * 0.8660254, -a / 3}, {0, 0, a}};
  for (const auto& v : p) h.vertices.insert(h.vertices.end(), {float(v.x()), float(v.y()), float(v.z())});
  const int loops[4][3] = {{0, 2, 1}, {0, 1, 3}, {1, 2, 3}, {2, 0, 3}};
  for (const auto& l : loops) {
    Vector3d v[3];
    for (int k = 0; k < 3; ++k) v[k] = Vector3d(h.vertex(l[k]));
    const Vector3d n = (v[1] - v[0]).cross(v[2] - v[0]).normalized();
    h.planes.insert(h.planes.end(), {float(n.x()), float(n.y()), float(n.z()), float(n.dot(v[0]))});
    h.face_vertices.insert(h.face_vertices.end(), {l[0], l[1], l[2]});
    h.face_start.push_back(int32_t(h.face_vertices.size()));
  }
  h.edges = {0, 1, 1, 2, 2, 0, 0, 3, 1, 3, 2, 3};
  return h;
}

TestHull dodecahedron(double r) {
  const double phi = (1 + std::sqrt(5.0)) / 2, s = r / std::sqrt(3.0);
  std::vector<Vector3d> p;
  for (int i = 0; i < 8; ++i) p.push_back(s * Vector3d(i & 1 ? 1 : -1, i & 2 ? 1 : -1, i & 4 ? 1 : -1));
  for (int i = 0; i < 4; ++i) {
    const double a = (i & 1 ? 1 : -1) / phi, b = (i & 2 ? 1 : -1) * phi;
    p.push_back(s * Vector3d(0, a, b)), p.push_back(s * Vector3d(a, b, 0)), p.push_back(s * Vector3d(b, 0, a));
  }
  return hull_from_points(p, 1e-5);
}

Quaterniond random_rotation(std::mt19937& rng) {
  std::normal_distribution<double> g;
  Quaterniond q(g(rng), g(rng), g(rng), g(rng));
  return q.normalized();
}
Vector3d random_direction(std::mt19937& rng) {
  std::normal_distribution<double> g;
  return Vector3d(g(rng), g(rng), g(rng)).normalized();
}

/// count points on an ellipsoid with random semi-axes: all in convex position.
TestHull random_hull(std::mt19937& rng, int count) {
  std::uniform_real_distribution<double> axis(0.3, 1.0);
  const Vector3d ax(axis(rng), axis(rng), axis(rng));
  std::vector<Vector3d> p;
  for (int i = 0; i < count; ++i) p.push_back(random_direction(rng).cwiseProduct(ax));
  return hull_from_points(p);
}

// ---- running and reference geometry ---------------------------------------------------------

std::vector<ContactPoint> run(const ShapeView& a, const Pose& pa, const ShapeView& b, const Pose& pb,
                              float margin = kMargin) {
  ContactPoint out[kMaxManifoldPoints];
  const int n = collide(a, pa, b, pb, margin, out);
  EXPECT_GE(n, 0);
  EXPECT_LE(n, kMaxManifoldPoints);
  return std::vector<ContactPoint>(out, out + std::max(0, n));
}

Vector3d P(const ContactPoint& c) { return {c.point[0], c.point[1], c.point[2]}; }
Vector3d N(const ContactPoint& c) { return {c.normal[0], c.normal[1], c.normal[2]}; }

Quaterniond quat(const Pose& p) {
  return Quaterniond(p.orientation[0], p.orientation[1], p.orientation[2], p.orientation[3]).normalized();
}

/// A convex polytope in world space for the reference: vertices, outward planes, edges.
struct World {
  std::vector<Vector3d> v, n;
  std::vector<double> d;
  std::vector<Vector3d> e;  // edge directions
  double size = 0;
};
World world(const TestHull& h, const Pose& p) {
  World w;
  const Quaterniond q = quat(p);
  const Vector3d t(p.position[0], p.position[1], p.position[2]);
  for (int i = 0; i < h.num_vertices(); ++i) w.v.push_back(t + q * (p.scale * h.vertex(i)));
  for (size_t f = 0; f + 1 < h.face_start.size(); ++f) {
    const Vector3d n = q * Vector3d(h.planes[4 * f], h.planes[4 * f + 1], h.planes[4 * f + 2]);
    w.n.push_back(n), w.d.push_back(p.scale * h.planes[4 * f + 3] + n.dot(t));
  }
  for (size_t k = 0; k < h.edges.size(); k += 2) w.e.push_back(w.v[h.edges[k + 1]] - w.v[h.edges[k]]);
  Vector3d c = Vector3d::Zero();
  for (const auto& v : w.v) c += v;
  c /= double(w.v.size());
  for (const auto& v : w.v) w.size = std::max(w.size, (v - c).norm());
  return w;
}
double support(const World& w, const Vector3d& u) {
  double m = -1e300;
  for (const auto& v : w.v) m = std::max(m, u.dot(v));
  return m;
}
/// How far B must move along unit u to clear A (negative: already apart along u by that).
double overlap_along(const World& A, const World& B, const Vector3d& u) { return support(A, u) + support(B, -u); }

/// Penetration depth by the separating axis theorem over every candidate axis, both signs
/// (negative: separated by at least that).
double reference_depth(const World& A, const World& B) {
  std::vector<Vector3d> axes = A.n;
  axes.insert(axes.end(), B.n.begin(), B.n.end());
  for (const auto& ea : A.e)
    for (const auto& eb : B.e) {
      const Vector3d c = ea.cross(eb);
      if (c.norm() > 1e-6 * ea.norm() * eb.norm()) axes.push_back(c.normalized());
    }
  double depth = 1e300;
  for (const auto& u : axes) depth = std::min({depth, overlap_along(A, B, u), overlap_along(A, B, -u)});
  return depth;
}
/// The same minimum over a dense Fibonacci sampling of directions (an upper bound).
double sampled_depth(const World& A, const World& B, int count = 4000) {
  double depth = 1e300;
  const double golden = kPi * (3 - std::sqrt(5.0));
  for (int i = 0; i < count; ++i) {
    const double z = 1 - 2 * (i + 0.5) / count, r = std::sqrt(1 - z * z);
    depth = std::min(depth, overlap_along(A, B, Vector3d(r * std::cos(golden * i), r * std::sin(golden * i), z)));
  }
  return depth;
}
/// Signed distance of x outside a world polytope (its largest plane distance).
double outside(const World& w, const Vector3d& x) {
  double h = -1e300;
  for (size_t f = 0; f < w.n.size(); ++f) h = std::max(h, w.n[f].dot(x) - w.d[f]);
  return h;
}

void expect_near3(const Vector3d& got, const Vector3d& want, double tol, const char* what = "") {
  EXPECT_LE((got - want).norm(), tol) << what << " got " << got.transpose() << " want " << want.transpose();
}

/// Every expected point matched by a distinct contact (any order).
void expect_points(const std::vector<ContactPoint>& got, std::vector<Vector3d> want, double tol) {
  ASSERT_EQ(got.size(), want.size());
  for (const auto& c : got) {
    auto best = want.begin();
    for (auto it = want.begin(); it != want.end(); ++it)
      if ((*it - P(c)).norm() < (*best - P(c)).norm()) best = it;
    EXPECT_LE((*best - P(c)).norm(), tol) << "unexpected point " << P(c).transpose();
    want.erase(best);
  }
}

bool same_bits(const std::vector<ContactPoint>& x, const std::vector<ContactPoint>& y) {
  return x.size() == y.size() && (x.empty() || std::memcmp(x.data(), y.data(), x.size() * sizeof(ContactPoint)) == 0);
}

/// collide(b, a) is collide(a, b) with the normals negated, bit for bit.
void expect_swap_symmetric(const ShapeView& a, const Pose& pa, const ShapeView& b, const Pose& pb, float margin = kMargin) {
  const auto ab = run(a, pa, b, pb, margin), ba = run(b, pb, a, pa, margin);
  ASSERT_EQ(ab.size(), ba.size());
  for (size_t i = 0; i < ab.size(); ++i) {
    ContactPoint f = ba[i];
    for (float& c : f.normal) c = -c;
    EXPECT_EQ(std::memcmp(&ab[i], &f, sizeof f), 0) << "contact " << i;
  }
}

// ---- closed forms ---------------------------------------------------------------------------

TEST(NarrowPhase, SphereSphere) {
  const Vector3d dir = Vector3d(1, 2, 2) / 3.0, ca(0.5, -1, 2);
  const auto c = run(sphere(1.0f), pose_at(ca), sphere(0.75f), pose_at(ca + 1.5 * dir));
  ASSERT_EQ(c.size(), 1u);
  expect_near3(N(c[0]), dir, 1e-6, "normal");
  EXPECT_NEAR(c[0].penetration, 0.25, 1e-6);
  expect_near3(P(c[0]), ca + 0.875 * dir, 1e-6, "point");  // surfaces at 1.0 and 0.75 along dir
}

TEST(NarrowPhase, SpherePlane) {
  const auto c = run(sphere(0.5f), pose_at({1, 2, 0.4}), plane({0, 0, 1}, 0.0f), Pose{});
  ASSERT_EQ(c.size(), 1u);
  expect_near3(N(c[0]), {0, 0, -1}, 1e-7);  // from the sphere to the plane
  EXPECT_NEAR(c[0].penetration, 0.1, 1e-6);
  expect_near3(P(c[0]), {1, 2, -0.05}, 1e-6);
  // A tilted plane, and the plane as a.
  const Vector3d n = Vector3d(0, 1, 1).normalized(), x = 0.3 * n + Vector3d(2, -0.2, 0.2) + 0.45 * n;
  const auto d = run(plane(n, 0.3f), Pose{}, sphere(0.5f), pose_at(x + Vector3d(0, 0.2, -0.2)));
  ASSERT_EQ(d.size(), 1u);
  expect_near3(N(d[0]), n, 1e-6);
  EXPECT_NEAR(d[0].penetration, 0.05, 1e-6);
}

TEST(NarrowPhase, SphereCapsuleAndSphereBox) {
  // Sphere beside a capsule's core, and beyond its end cap.
  auto c = run(sphere(0.3f), pose_at({0.5, 0, 0.2}), capsule(0.25f, 0.5f), pose_at({0, 0, 0}));
  ASSERT_EQ(c.size(), 1u);
  expect_near3(N(c[0]), {-1, 0, 0}, 1e-6);
  EXPECT_NEAR(c[0].penetration, 0.05, 1e-6);
  expect_near3(P(c[0]), {0.225, 0, 0.2}, 1e-6);
  c = run(sphere(0.3f), pose_at({0, 0, 1.0}), capsule(0.25f, 0.5f), pose_at({0, 0, 0}));
  ASSERT_EQ(c.size(), 1u);
  expect_near3(N(c[0]), {0, 0, -1}, 1e-6);
  EXPECT_NEAR(c[0].penetration, 0.05, 1e-6);
  // Sphere against a box face, edge and corner, and with its centre inside.
  const ShapeView b = box(1, 1, 1);
  c = run(sphere(0.4f), pose_at({0.3, -0.2, 1.3}), b, Pose{});
  ASSERT_EQ(c.size(), 1u);
  expect_near3(N(c[0]), {0, 0, -1}, 1e-6);
  EXPECT_NEAR(c[0].penetration, 0.1, 1e-6);
  const Vector3d corner(1, 1, 1), diag = Vector3d(1, 1, 1).normalized();
  c = run(sphere(0.4f), pose_at(corner + 0.3 * diag), b, Pose{});
  ASSERT_EQ(c.size(), 1u);
  expect_near3(N(c[0]), -diag, 1e-6);
  EXPECT_NEAR(c[0].penetration, 0.1, 1e-6);
  expect_near3(P(c[0]), corner - 0.05 * diag, 1e-6);
  c = run(sphere(0.4f), pose_at({1.2, 0.5, 1.2}), b, Pose{});  // over the edge x = z = 1
  ASSERT_EQ(c.size(), 1u);
  EXPECT_NEAR(c[0].penetration, 0.4 - 0.2 * std::sqrt(2.0), 1e-6);
  c = run(sphere(0.4f), pose_at({0.2, 0.1, 0.9}), b, Pose{});  // centre inside, 0.1 under the top
  ASSERT_EQ(c.size(), 1u);
  expect_near3(N(c[0]), {0, 0, -1}, 1e-6);
  EXPECT_NEAR(c[0].penetration, 0.5, 1e-6);
  // The same sphere-box contacts with the box as a hull, under a rotation.
  std::mt19937 rng(7);
  const TestHull bh = box_hull(1, 0.5f, 0.25f);
  for (int i = 0; i < 200; ++i) {
    const Pose pb = pose_at(Vector3d(0.1, 0.2, 0.3), random_rotation(rng));
    const Pose ps = pose_at(Vector3d(0.1, 0.2, 0.3) + random_direction(rng) * std::uniform_real_distribution<>(0, 1.5)(rng));
    const auto x = run(sphere(0.4f), ps, box(1, 0.5f, 0.25f), pb), y = run(sphere(0.4f), ps, bh.shape(), pb);
    ASSERT_EQ(x.size(), y.size()) << i;
    for (size_t k = 0; k < x.size(); ++k) {
      expect_near3(P(x[k]), P(y[k]), 1e-5), expect_near3(N(x[k]), N(y[k]), 1e-5);
      EXPECT_NEAR(x[k].penetration, y[k].penetration, 1e-5);
    }
  }
}

TEST(NarrowPhase, BoxPlaneRestingFlat) {
  const auto c = run(box(0.5f, 0.3f, 0.2f), pose_at({1, 2, 0.15}), plane({0, 0, 1}, 0.0f), Pose{});
  ASSERT_EQ(c.size(), 4u);
  for (const auto& p : c) {
    expect_near3(N(p), {0, 0, -1}, 0);
    EXPECT_NEAR(p.penetration, 0.05, 1e-7);
  }
  expect_points(c, {{0.5, 1.7, -0.025}, {1.5, 1.7, -0.025}, {0.5, 2.3, -0.025}, {1.5, 2.3, -0.025}}, 1e-6);
}

TEST(NarrowPhase, BoxPlaneTilted) {
  const float hx = 0.5f, hy = 0.3f, hz = 0.2f;
  // About x by 30 degrees: the bottom edge along x, two corners at the same depth.
  const double a = kPi / 6, low = hy * std::sin(a) + hz * std::cos(a);
  auto c = run(box(hx, hy, hz), pose_at({0, 0, low - 0.02}, rot(a, {1, 0, 0})), plane({0, 0, 1}, 0.0f), Pose{}, 0.0f);
  ASSERT_EQ(c.size(), 2u);
  for (const auto& p : c) {
    EXPECT_NEAR(p.penetration, 0.02, 1e-6);
    EXPECT_NEAR(std::fabs(P(p).x()), hx, 1e-6);
    EXPECT_NEAR(P(p).z(), -0.01, 1e-6);
  }
  // A generic tilt: one lowest corner, depth from the corners' heights.
  const Quaterniond q = rot(0.7, {1, 2, 3});
  std::vector<double> z;
  Vector3d lowest = Vector3d::Zero();
  for (int i = 0; i < 8; ++i) {
    const Vector3d v = q * Vector3d(i & 1 ? hx : -hx, i & 2 ? hy : -hy, i & 4 ? hz : -hz);
    if (z.empty() || v.z() < *std::min_element(z.begin(), z.end())) lowest = v;
    z.push_back(v.z());
  }
  std::sort(z.begin(), z.end());
  ASSERT_GT(z[1] - z[0], 0.05);  // the second corner stays clear of the plane
  const Vector3d centre(0.3, -0.4, -z[0] - 0.03);
  c = run(box(hx, hy, hz), pose_at(centre, q), plane({0, 0, 1}, 0.0f), Pose{}, 0.0f);
  ASSERT_EQ(c.size(), 1u);
  EXPECT_NEAR(c[0].penetration, 0.03, 1e-6);
  expect_near3(P(c[0]), centre + lowest + Vector3d(0, 0, 0.015), 1e-6);
}

TEST(NarrowPhase, BoxBoxStackedOffset) {
  // b (0.5 cube) rests 0.1 deep on a's top (z = 0.5), offset so the overlap is [0.3,1]x[0.2,1].
  const ShapeView a = box(1, 1, 0.5f), b = box(0.5f, 0.5f, 0.5f);
  const Pose pa = pose_at({0, 0, 0}), pb = pose_at({0.8, 0.7, 0.9});
  const auto c = run(a, pa, b, pb);
  ASSERT_EQ(c.size(), 4u);
  for (const auto& p : c) {
    expect_near3(N(p), {0, 0, 1}, 1e-7);
    EXPECT_NEAR(p.penetration, 0.1, 1e-6);
  }
  expect_points(c, {{0.3, 0.2, 0.45}, {1, 0.2, 0.45}, {0.3, 1, 0.45}, {1, 1, 0.45}}, 1e-6);
  const auto d = run(b, pb, a, pa);
  ASSERT_EQ(d.size(), 4u);
  for (const auto& p : d) expect_near3(N(p), {0, 0, -1}, 1e-7);
  // b smaller than a's face, resting inside it: b's bottom face.
  const auto e = run(a, pa, b, pose_at({0.1, -0.2, 0.95}));
  expect_points(e, {{-0.4, -0.7, 0.475}, {0.6, -0.7, 0.475}, {-0.4, 0.3, 0.475}, {0.6, 0.3, 0.475}}, 1e-6);
}

TEST(NarrowPhase, BoxBoxEdgeEdge) {
  // a's top edge along x (rotated 45 deg about x), b's bottom edge along y (45 deg about y),
  // crossing 0.1 deep; then the whole scene under a rotation Q.
  const double r2 = std::sqrt(0.5), depth = 0.1;
  for (const Quaterniond& Q : {Quaterniond::Identity(), rot(0.9, {0.3, -1, 0.5})}) {
    const Pose pa = pose_at(Q * Vector3d(0, 0, 0), Q * rot(kPi / 4, {1, 0, 0}));
    const Pose pb = pose_at(Q * Vector3d(0, 0, 2 * r2 - depth), Q * rot(kPi / 4, {0, 1, 0}));
    const auto c = run(box(0.5f, 0.5f, 0.5f), pa, box(0.5f, 0.5f, 0.5f), pb);
    ASSERT_EQ(c.size(), 1u);
    expect_near3(N(c[0]), Q * Vector3d(0, 0, 1), 1e-6, "normal = x cross y");
    EXPECT_NEAR(c[0].penetration, depth, 1e-6);
    expect_near3(P(c[0]), Q * Vector3d(0, 0, r2 - depth / 2), 1e-6);
    expect_swap_symmetric(box(0.5f, 0.5f, 0.5f), pa, box(0.5f, 0.5f, 0.5f), pb);
  }
}

TEST(NarrowPhase, CapsuleBoxLyingFlat) {
  // Core along x at height 0.58 over a box top at 0.5: radius 0.1, so 0.02 deep at both ends.
  const TestHull bh = box_hull(1, 1, 0.5f);
  for (const ShapeView& b : {box(1, 1, 0.5f), bh.shape()}) {
    const auto c = run(capsule(0.1f, 0.5f), pose_at({0.2, 0, 0.58}, rot(kPi / 2, {0, 1, 0})), b, Pose{});
    ASSERT_EQ(c.size(), 2u);
    for (const auto& p : c) {
      expect_near3(N(p), {0, 0, -1}, 1e-6);
      EXPECT_NEAR(p.penetration, 0.02, 1e-6);
    }
    expect_points(c, {{-0.3, 0, 0.49}, {0.7, 0, 0.49}}, 1e-6);
    // Hanging over the edge x = 1: the part over the face, ending at the edge.
    const auto d = run(capsule(0.1f, 0.5f), pose_at({0.8, 0, 0.58}, rot(kPi / 2, {0, 1, 0})), b, Pose{});
    expect_points(d, {{0.3, 0, 0.49}, {1.0, 0, 0.49}}, 1e-6);
    // Standing on its end: one point.
    const auto e = run(capsule(0.1f, 0.5f), pose_at({0.2, 0.1, 1.08}), b, Pose{});
    ASSERT_EQ(e.size(), 1u);
    EXPECT_NEAR(e[0].penetration, 0.02, 1e-6);
    // Core pushed into the face: the two ends, deeper.
    const auto f = run(capsule(0.1f, 0.5f), pose_at({0.2, 0, 0.45}, rot(kPi / 2, {0, 1, 0})), b, Pose{});
    ASSERT_EQ(f.size(), 2u);
    for (const auto& p : f) EXPECT_NEAR(p.penetration, 0.15, 1e-6);
  }
}

TEST(NarrowPhase, CapsuleCapsule) {
  // Crossing: a along x, b along y above it, 0.05 deep.
  auto c = run(capsule(0.1f, 0.5f), pose_at({0, 0, 0}, rot(kPi / 2, {0, 1, 0})), capsule(0.1f, 0.5f),
               pose_at({0, 0, 0.15}, rot(kPi / 2, {1, 0, 0})));
  ASSERT_EQ(c.size(), 1u);
  expect_near3(N(c[0]), {0, 0, 1}, 1e-6);
  EXPECT_NEAR(c[0].penetration, 0.05, 1e-6);
  expect_near3(P(c[0]), {0, 0, 0.075}, 1e-6);
  // Side by side, parallel and offset along the axis: the ends of the overlap.
  c = run(capsule(0.1f, 0.5f), pose_at({0, 0, 0}), capsule(0.2f, 0.5f), pose_at({0.25, 0, 0.4}));
  ASSERT_EQ(c.size(), 2u);
  for (const auto& p : c) {
    expect_near3(N(p), {1, 0, 0}, 1e-6);
    EXPECT_NEAR(p.penetration, 0.05, 1e-6);
  }
  expect_points(c, {{0.075, 0, -0.1}, {0.075, 0, 0.5}}, 1e-6);
  // Cores crossing exactly: perpendicular to both, finite.
  c = run(capsule(0.1f, 0.5f), pose_at({0, 0, 0}), capsule(0.1f, 0.5f), pose_at({0, 0, 0}, rot(kPi / 2, {1, 0, 0})));
  ASSERT_EQ(c.size(), 1u);
  EXPECT_NEAR(N(c[0]).norm(), 1.0, 1e-6);
  EXPECT_NEAR(N(c[0]).dot(Vector3d(0, 0, 1)), 0.0, 1e-6);
  EXPECT_NEAR(N(c[0]).dot(Vector3d(0, 1, 0)), 0.0, 1e-6);
  EXPECT_NEAR(c[0].penetration, 0.2, 1e-6);
}

TEST(NarrowPhase, CapsulePlane) {
  const ShapeView floor = plane({0, 0, 1}, 0.0f);
  auto c = run(capsule(0.1f, 0.5f), pose_at({0, 0, 0.08}, rot(kPi / 2, {0, 1, 0})), floor, Pose{});
  expect_points(c, {{-0.5, 0, -0.01}, {0.5, 0, -0.01}}, 1e-6);
  for (const auto& p : c) EXPECT_NEAR(p.penetration, 0.02, 1e-6);
  c = run(capsule(0.1f, 0.5f), pose_at({0, 0, 0.58}, rot(0.3, {0, 1, 0})), floor, Pose{});
  ASSERT_EQ(c.size(), 1u);
  EXPECT_NEAR(c[0].penetration, 0.1 - (0.58 - 0.5 * std::cos(0.3)), 1e-6);
}

TEST(NarrowPhase, HullPlane) {
  // A dodecahedron resting on a pentagon: its five corners, reduced to four spanning ones.
  const TestHull dod = dodecahedron(1.0);
  ASSERT_EQ(dod.num_vertices(), 20);
  ASSERT_EQ(dod.planes.size() / 4, 12u);
  // Rotate the first face's normal onto -z, then sink by 0.01.
  const Vector3d n0(dod.planes[0], dod.planes[1], dod.planes[2]);
  const Quaterniond q = Quaterniond::FromTwoVectors(n0, Vector3d(0, 0, -1));
  const Pose p = pose_at({0.5, 0.5, dod.planes[3] - 0.01}, q);
  const auto c = run(dod.shape(), p, plane({0, 0, 1}, 0.0f), Pose{});
  ASSERT_EQ(c.size(), 4u);
  for (const auto& x : c) {
    EXPECT_NEAR(x.penetration, 0.01, 2e-6);
    EXPECT_NEAR(P(x).z(), -0.005, 2e-6);
  }
  // A tetrahedron on its base: three points; on its apex: one.
  const TestHull t = tetrahedron(1.0f);
  EXPECT_EQ(run(t.shape(), pose_at({0, 0, 1.0 / 3 - 0.01}), plane({0, 0, 1}, 0.0f), Pose{}).size(), 3u);
  const auto d = run(t.shape(), pose_at({0, 0, 0.99}, rot(kPi, {1, 0, 0})), plane({0, 0, 1}, 0.0f), Pose{});
  ASSERT_EQ(d.size(), 1u);
  EXPECT_NEAR(d[0].penetration, 0.01, 1e-6);
}

TEST(NarrowPhase, DeepBoxInBox) {
  // A small box inside a big one: pushed out through the nearest face, 0.75 to clear it.
  const auto c = run(box(1, 1, 1), Pose{}, box(0.25f, 0.25f, 0.25f), pose_at({0, 0, 0.5}));
  ASSERT_EQ(c.size(), 4u);
  for (const auto& p : c) {
    expect_near3(N(p), {0, 0, 1}, 1e-7);
    EXPECT_NEAR(p.penetration, 0.75, 1e-6);
    EXPECT_NEAR(P(p).z(), 0.625, 1e-6);
  }
  // Exactly concentric: still a finite unit normal and the full depth.
  const auto d = run(box(1, 1, 1), Pose{}, box(0.25f, 0.25f, 0.25f), Pose{});
  ASSERT_GE(d.size(), 1u);
  for (const auto& p : d) {
    EXPECT_NEAR(N(p).norm(), 1.0, 1e-6);
    EXPECT_NEAR(p.penetration, 1.25, 1e-6);
  }
}

TEST(NarrowPhase, ExactlyTouching) {
  struct Case {
    ShapeView a;
    Pose pa;
    ShapeView b;
    Pose pb;
    size_t points;
  };
  const Case cases[] = {
      {sphere(0.5f), pose_at({0, 0, 0}), sphere(0.5f), pose_at({1, 0, 0}), 1},
      {sphere(0.5f), pose_at({0, 0, 0.5}), plane({0, 0, 1}, 0.0f), Pose{}, 1},
      {box(0.5f, 0.5f, 0.5f), pose_at({0, 0, 0.5}), plane({0, 0, 1}, 0.0f), Pose{}, 4},
      {box(1, 1, 0.5f), Pose{}, box(0.5f, 0.5f, 0.5f), pose_at({0.25, 0, 1}), 4},
      {capsule(0.25f, 0.5f), pose_at({0, 0, 0.75}), plane({0, 0, 1}, 0.0f), Pose{}, 1},
      {sphere(0.25f), pose_at({0, 0, 0.75}), box(1, 1, 0.5f), Pose{}, 1},
  };
  for (const auto& k : cases) {
    const auto c = run(k.a, k.pa, k.b, k.pb, kMargin);
    ASSERT_EQ(c.size(), k.points);
    for (const auto& p : c) EXPECT_EQ(p.penetration, 0.0f);
    EXPECT_TRUE(run(k.a, k.pa, k.b, k.pb, 0.0f).empty()) << "margin 0 keeps overlap only";
  }
}

TEST(NarrowPhase, CoincidentSphereCentres) {
  const auto c = run(sphere(0.5f), pose_at({1, 2, 3}), sphere(0.25f), pose_at({1, 2, 3}));
  ASSERT_EQ(c.size(), 1u);
  for (int i = 0; i < 3; ++i) EXPECT_TRUE(std::isfinite(c[0].normal[i]) && std::isfinite(c[0].point[i]));
  EXPECT_NEAR(N(c[0]).norm(), 1.0, 1e-7);
  EXPECT_EQ(c[0].penetration, 0.75f);
  // Sphere centre on a capsule's core, and at a box's centre.
  const auto d = run(sphere(0.5f), pose_at({0, 0, 0.2}), capsule(0.25f, 0.5f), Pose{});
  ASSERT_EQ(d.size(), 1u);
  EXPECT_NEAR(N(d[0]).norm(), 1.0, 1e-7);
  EXPECT_NEAR(N(d[0]).z(), 0.0, 1e-7);
  const auto e = run(sphere(0.5f), Pose{}, box(1, 1, 1), Pose{});
  ASSERT_EQ(e.size(), 1u);
  EXPECT_NEAR(e[0].penetration, 1.5, 1e-7);
}

// ---- every pair of types --------------------------------------------------------------------

struct Catalogue {
  TestHull dod = dodecahedron(0.6), tet = tetrahedron(0.7f);
  std::vector<ShapeView> shapes;
  std::vector<double> radius;  // bounding sphere about the body origin
  Catalogue() {
    shapes = {sphere(0.5f), capsule(0.3f, 0.5f), box(0.5f, 0.4f, 0.3f), dod.shape(), plane({0, 0, 1}, 0.0f), tet.shape()};
    radius = {0.5, 0.8, std::sqrt(0.5), 0.6, 0.0, 0.75};
  }
};

TEST(NarrowPhase, SeparatedPairsGiveNothing) {
  Catalogue cat;
  std::mt19937 rng(3);
  for (size_t i = 0; i < cat.shapes.size(); ++i)
    for (size_t j = 0; j < cat.shapes.size(); ++j)
      for (int trial = 0; trial < 50; ++trial) {
        const ShapeView &a = cat.shapes[i], &b = cat.shapes[j];
        const bool pi = a.type == ShapeType::plane, pj = b.type == ShapeType::plane;
        Pose pa = pi ? Pose{} : pose_at(Vector3d(0.1, -0.2, 2.0), random_rotation(rng));
        const Vector3d dir = pi ? Vector3d(0, 0, 1) : (pj ? Vector3d(0, 0, -1) : random_direction(rng));
        const double gap = kMargin + 0.02 + 0.1 * trial / 50.0;
        const Vector3d from = pi ? Vector3d(0.3, 0.1, 0) : Vector3d(0.1, -0.2, 2.0);
        const double reach = (pi ? 0 : cat.radius[i]) + (pj ? 0 : cat.radius[j]);
        Pose pb = pj ? Pose{} : pose_at(from + dir * (reach + gap), random_rotation(rng));
        if (pj) pa = pose_at(Vector3d(0.1, -0.2, cat.radius[i] + gap), random_rotation(rng));
        EXPECT_TRUE(run(a, pa, b, pb).empty()) << "types " << i << " " << j << " trial " << trial;
      }
}

TEST(NarrowPhase, SpeculativeMargin) {
  // A gap inside the margin gives a contact with negative penetration; beyond it, none.
  auto c = run(sphere(0.5f), pose_at({0, 0, 0}), sphere(0.5f), pose_at({1.005, 0, 0}));
  ASSERT_EQ(c.size(), 1u);
  EXPECT_NEAR(c[0].penetration, -0.005, 1e-6);
  EXPECT_TRUE(run(sphere(0.5f), pose_at({0, 0, 0}), sphere(0.5f), pose_at({1.015, 0, 0})).empty());
  c = run(box(1, 1, 0.5f), Pose{}, box(0.5f, 0.5f, 0.5f), pose_at({0.2, 0, 1.005}));
  ASSERT_EQ(c.size(), 4u);
  for (const auto& p : c) EXPECT_NEAR(p.penetration, -0.005, 1e-6);
  EXPECT_TRUE(run(box(1, 1, 0.5f), Pose{}, box(0.5f, 0.5f, 0.5f), pose_at({0.2, 0, 1.015})).empty());
  c = run(capsule(0.1f, 0.5f), pose_at({0, 0, 0.605}, rot(kPi / 2, {0, 1, 0})), box(1, 1, 0.5f), Pose{});
  ASSERT_EQ(c.size(), 2u);
  for (const auto& p : c) EXPECT_NEAR(p.penetration, -0.005, 1e-6);
  EXPECT_TRUE(run(box(0.5f, 0.5f, 0.5f), pose_at({0, 0, 0.515}), plane({0, 0, 1}, 0), Pose{}).empty());
}

TEST(NarrowPhase, SwapFlipsNormalsForEveryPair) {
  Catalogue cat;
  std::mt19937 rng(11);
  int contacts = 0;
  for (size_t i = 0; i < cat.shapes.size(); ++i)
    for (size_t j = 0; j < cat.shapes.size(); ++j)
      for (int trial = 0; trial < 60; ++trial) {
        const ShapeView &a = cat.shapes[i], &b = cat.shapes[j];
        const bool pi = a.type == ShapeType::plane, pj = b.type == ShapeType::plane;
        std::uniform_real_distribution<double> u(0.0, 1.0);
        const double reach = (pi ? 0 : cat.radius[i]) + (pj ? 0 : cat.radius[j]);
        const Pose pa = pi ? Pose{} : pose_at(Vector3d(0.2, 0.1, pj ? reach * u(rng) : 0.0), random_rotation(rng));
        const Pose pb = pj ? Pose{}
                           : pose_at(pi ? Vector3d(-0.3, 0.2, reach * u(rng)) : random_direction(rng) * reach * u(rng),
                                     random_rotation(rng));
        expect_swap_symmetric(a, pa, b, pb);
        contacts += int(run(a, pa, b, pb).size());
        if (i == j && !pi) {  // coincident: finite unit normals
          for (const auto& c : run(a, pa, b, pa)) EXPECT_NEAR(N(c).norm(), 1.0, 1e-6);
        }
      }
  EXPECT_GT(contacts, 1000);
}

/// b translated by t.
World moved(World w, const Vector3d& t) {
  for (auto& v : w.v) v += t;
  for (size_t f = 0; f < w.n.size(); ++f) w.d[f] += w.n[f].dot(t);
  return w;
}

/// Checks a polytope pair's contacts against the reference. Always: contacts iff the shapes
/// overlap, one unit normal, close to the least-penetration axis (within the face/edge bias),
/// no point deeper than the overlap along it, swap symmetry. For shallow contacts, the ones a
/// penalty method lives with, also the meaning of each point (a's surface point, point + n
/// pen/2, is on a; b's, point - n pen/2, on b) and that moving b along the normal by the
/// deepest penetration separates the shapes. (Deep in, the clipped incident face need not
/// hold the deepest vertex: that is the method, not a defect.)
/// sa and sb are what the engine sees (a hull, or a box); ha and hb the same as test hulls.
void check_polytope_pair(const ShapeView& sa, const TestHull& ha, const Pose& pa, const ShapeView& sb,
                         const TestHull& hb, const Pose& pb, int trial, bool shallow) {
  const World A = world(ha, pa), B = world(hb, pb);
  const double ref = reference_depth(A, B), tol = 1e-5 * (A.size + B.size);
  const auto c = run(sa, pa, sb, pb, 0.0f);
  SCOPED_TRACE(testing::Message() << "trial " << trial << " reference depth " << ref);
  if (ref < -tol) {
    ASSERT_TRUE(c.empty());
  }
  if (ref > tol) {
    ASSERT_FALSE(c.empty());
  }
  if (c.empty()) return;
  const Vector3d n = N(c[0]);
  EXPECT_NEAR(n.norm(), 1.0, 1e-6);
  double deepest = -1e300;
  for (const auto& p : c) {
    expect_near3(N(p), n, 0, "one normal per manifold");
    deepest = std::max(deepest, double(p.penetration));
    if (!shallow) continue;
    EXPECT_LE(outside(A, P(p) + n * (p.penetration / 2)), tol) << "a's surface point is on a";
    EXPECT_LE(outside(B, P(p) - n * (p.penetration / 2)), tol) << "b's surface point is on b";
  }
  const double along = overlap_along(A, B, n);
  EXPECT_LE(deepest, along + tol);
  const double bias = 5e-4 * std::min(A.size, B.size);
  EXPECT_LE(along, 1.08 * ref + 2 * bias + tol) << "the normal is (nearly) the least-penetration axis";
  const double sampled = sampled_depth(A, B);
  EXPECT_GE(sampled, ref - tol) << "no sampled direction beats the separating axes";
  EXPECT_LE(deepest, 1.08 * sampled + 2 * bias + tol) << "the penetration is (nearly) the least over all directions";
  if (shallow) {  // within the absolute tolerance of the axis choice
    EXPECT_LE(reference_depth(A, moved(B, n * (deepest + tol))), 2 * bias) << "b moved by n * penetration is clear of a";
    EXPECT_GE(deepest, ref - 2 * bias);
  }
  expect_swap_symmetric(sa, pa, sb, pb, 0.0f);
}
void check_polytope_pair(const TestHull& ha, const Pose& pa, const TestHull& hb, const Pose& pb, int trial, bool shallow) {
  check_polytope_pair(ha.shape(), ha, pa, hb.shape(), hb, pb, trial, shallow);
}

/// b's position along dir from a's where the two just touch (bisection on the reference).
double touching_distance(const TestHull& ha, const Pose& pa, const TestHull& hb, Pose pb, const Vector3d& dir) {
  const World A = world(ha, pa);
  const Vector3d from(pa.position[0], pa.position[1], pa.position[2]);
  double lo = 0, hi = 4;
  for (int i = 0; i < 60; ++i) {
    const double mid = 0.5 * (lo + hi);
    const Vector3d p = from + dir * mid;
    for (int k = 0; k < 3; ++k) pb.position[k] = float(p[k]);
    (reference_depth(A, world(hb, pb)) > 0 ? lo : hi) = mid;
  }
  return lo;
}

TEST(NarrowPhase, HullHullAgainstBruteForce) {
  std::mt19937 rng(2024);
  int overlapping = 0;
  for (int trial = 0; trial < 600; ++trial) {
    const TestHull ha = trial % 4 == 0 ? tetrahedron(0.8f) : random_hull(rng, 6 + trial % 11);
    const TestHull hb = trial % 5 == 0 ? tetrahedron(0.6f) : random_hull(rng, 5 + trial % 13);
    ASSERT_TRUE(hull_supported(ha.shape().hull));
    ASSERT_TRUE(hull_supported(hb.shape().hull));
    const Vector3d from(0.3, -0.1, 0.2), dir = random_direction(rng);
    const Pose pa = pose_at(from, random_rotation(rng));
    Pose pb = pose_at(from, random_rotation(rng));
    // Odd trials: anywhere from coincident to apart. Even: within 2 cm of touching.
    const bool shallow = trial % 2 == 0;
    const double dist = shallow ? touching_distance(ha, pa, hb, pb, dir) + std::uniform_real_distribution<>(-0.02, 0.005)(rng)
                                : std::uniform_real_distribution<>(0.0, 1.6)(rng);
    pb = pose_at(from + dir * dist, quat(pb));
    overlapping += reference_depth(world(ha, pa), world(hb, pb)) > 0;
    check_polytope_pair(ha, pa, hb, pb, trial, shallow);
  }
  EXPECT_GT(overlapping, 300);
}

TEST(NarrowPhase, BoxesAgainstBruteForceAndTheirHulls) {
  // Boxes through the engine's own box path, checked like hulls, and equal to box hulls.
  std::mt19937 rng(5);
  const TestHull ha = box_hull(0.6f, 0.4f, 0.3f), hb = box_hull(0.5f, 0.5f, 0.2f);
  const ShapeView ba = box(0.6f, 0.4f, 0.3f), bb = box(0.5f, 0.5f, 0.2f);
  const TestHull dod = dodecahedron(0.6);
  for (int trial = 0; trial < 300; ++trial) {
    SCOPED_TRACE(testing::Message() << "trial " << trial);
    const Pose pa = pose_at(Vector3d(0, 0, 0), random_rotation(rng));
    const Vector3d dir = random_direction(rng);
    Pose pb = pose_at(Vector3d(0, 0, 0), random_rotation(rng));
    const bool shallow = trial % 2 == 0;
    const double dist = shallow ? touching_distance(ha, pa, hb, pb, dir) + std::uniform_real_distribution<>(-0.02, 0.005)(rng)
                                : std::uniform_real_distribution<>(0.0, 1.4)(rng);
    pb = pose_at(dir * dist, quat(pb));
    check_polytope_pair(ha, pa, hb, pb, trial, shallow);
    check_polytope_pair(ba, ha, pa, bb, hb, pb, trial, shallow);
    // The box path and the hull path agree. (Points only up to the choice among near-equal
    // candidates when more than four are reduced: they differ in rounding, not in quality.)
    const auto boxes = run(ba, pa, bb, pb), hulls = run(ha.shape(), pa, hb.shape(), pb);
    ASSERT_EQ(boxes.size(), hulls.size());
    if (!boxes.empty()) {
      expect_near3(N(boxes[0]), N(hulls[0]), 1e-5);
      double db = -1e9, dh = -1e9;
      for (size_t k = 0; k < boxes.size(); ++k)
        db = std::max(db, double(boxes[k].penetration)), dh = std::max(dh, double(hulls[k].penetration));
      EXPECT_NEAR(db, dh, 1e-5);
    }
    // Box against a hull and a plane, and a capsule against the box and its hull.
    check_polytope_pair(ba, ha, pa, dod.shape(), dod, pb, trial, false);
    const Pose tilt = pose_at({0, 0, std::uniform_real_distribution<>(0.0, 0.7)(rng)}, random_rotation(rng));
    const auto bp = run(ba, tilt, plane({0, 0, 1}, 0), Pose{}), hp = run(ha.shape(), tilt, plane({0, 0, 1}, 0), Pose{});
    ASSERT_EQ(bp.size(), hp.size());
    std::vector<Vector3d> wp;
    for (const auto& p : hp) wp.push_back(P(p));
    expect_points(bp, wp, 1e-5);
    const auto cb = run(capsule(0.2f, 0.4f), pb, ba, pa), ch = run(capsule(0.2f, 0.4f), pb, ha.shape(), pa);
    ASSERT_EQ(cb.size(), ch.size()) << trial;
    for (size_t k = 0; k < cb.size(); ++k) {
      expect_near3(P(cb[k]), P(ch[k]), 1e-5), expect_near3(N(cb[k]), N(ch[k]), 1e-5);
      EXPECT_NEAR(cb[k].penetration, ch[k].penetration, 1e-5);
    }
  }
}

/// Distance from point x to segment p0 p1.
double point_segment(const Vector3d& x, const Vector3d& p0, const Vector3d& p1) {
  const Vector3d u = p1 - p0;
  const double t = u.squaredNorm() > 0 ? std::clamp((x - p0).dot(u) / u.squaredNorm(), 0.0, 1.0) : 0.0;
  return (x - (p0 + t * u)).norm();
}
/// Distance between two segments by ternary search along the first (the distance to a
/// segment is convex along a line): slow, and shares nothing with the engine.
double segment_segment(const Vector3d& a0, const Vector3d& a1, const Vector3d& b0, const Vector3d& b1) {
  auto f = [&](double t) { return point_segment(a0 + t * (a1 - a0), b0, b1); };
  double lo = 0, hi = 1;
  for (int i = 0; i < 200; ++i) {
    const double m1 = lo + (hi - lo) / 3, m2 = hi - (hi - lo) / 3;
    (f(m1) < f(m2) ? hi : lo) = f(m1) < f(m2) ? m2 : m1;
  }
  return f(0.5 * (lo + hi));
}
/// Distance from a segment to a hull's surface by triangles (each face as a fan): endpoints
/// against triangles, the segment against triangle edges. Negative if the segment crosses a face.
double segment_hull(const TestHull& h, const World& w, const Vector3d& p0, const Vector3d& p1) {
  double best = 1e300;
  for (size_t f = 0; f + 1 < h.face_start.size(); ++f) {
    const int b = h.face_start[f], e = h.face_start[f + 1];
    for (int k = b + 1; k + 1 < e; ++k) {
      const Vector3d t[3] = {w.v[h.face_vertices[b]], w.v[h.face_vertices[k]], w.v[h.face_vertices[k + 1]]};
      const Vector3d n = (t[1] - t[0]).cross(t[2] - t[0]).normalized();
      auto inside = [&](const Vector3d& y) {
        for (int q = 0; q < 3; ++q)
          if ((t[(q + 1) % 3] - t[q]).cross(y - t[q]).dot(n) < 0) return false;
        return true;
      };
      const double h0 = n.dot(p0 - t[0]), h1 = n.dot(p1 - t[0]);
      if (h0 * h1 < 0) {  // crosses the plane: inside the triangle means through the surface
        const Vector3d y = p0 + (h0 / (h0 - h1)) * (p1 - p0);
        if (inside(y)) return -1;
      }
      for (const Vector3d& p : {p0, p1}) {
        const double hp = n.dot(p - t[0]);
        if (inside(p - hp * n)) best = std::min(best, std::fabs(hp));
      }
      for (int q = 0; q < 3; ++q) best = std::min(best, segment_segment(p0, p1, t[q], t[(q + 1) % 3]));
    }
  }
  return best;
}

TEST(NarrowPhase, CapsuleAndSphereAgainstHulls) {
  // Random capsules and spheres near random hulls: a's surface point lies on the capsule, b's
  // on the hull; where the core stays outside, the deepest penetration is the radius less the
  // reference distance (both exact for a sphere; for a capsule lying along a face within the
  // small tilt that reports the face's two clipped ends, up to that tilt); where the core
  // crosses the hull, it is at least the radius.
  std::mt19937 rng(9);
  int apart = 0, crossing = 0;
  for (int trial = 0; trial < 300; ++trial) {
    SCOPED_TRACE(testing::Message() << "trial " << trial);
    const TestHull h = random_hull(rng, 8 + trial % 9);
    const Pose ph = pose_at(Vector3d(0, 0, 0), random_rotation(rng));
    const Pose pc = pose_at(random_direction(rng) * std::uniform_real_distribution<>(0.0, 1.4)(rng), random_rotation(rng));
    const bool sph = trial % 3 == 0;
    const float r = 0.15f, hh = sph ? 0.0f : 0.4f;
    const auto c = sph ? run(sphere(r), pc, h.shape(), ph, 0.0f) : run(capsule(r, hh), pc, h.shape(), ph, 0.0f);
    const World W = world(h, ph);
    const Vector3d axis = quat(pc) * Vector3d(0, 0, hh), mid(pc.position[0], pc.position[1], pc.position[2]);
    const double dist = segment_hull(h, W, mid - axis, mid + axis);
    double deepest = -1e300;
    for (const auto& p : c) {
      const Vector3d n = N(p), sa = P(p) + n * (p.penetration / 2), sb = P(p) - n * (p.penetration / 2);
      EXPECT_LE(point_segment(sa, mid - axis, mid + axis), r + 1e-5);
      EXPECT_LE(outside(W, sb), 1e-5);
      deepest = std::max(deepest, double(p.penetration));
    }
    const bool core_in = dist < 0 || outside(W, mid - axis) <= 0 || outside(W, mid + axis) <= 0;
    if (core_in) {
      ++crossing;
      ASSERT_FALSE(c.empty());
      EXPECT_GE(deepest, r - 1e-5);
    } else if (dist < r - 1e-5) {
      ++apart;
      ASSERT_FALSE(c.empty());
      EXPECT_LE(deepest, r - dist + 1e-5);
      EXPECT_GE(deepest, r - dist - (sph ? 1e-5 : 2 * hh * 0.045)) << "distance " << dist;
    } else if (dist > r + 1e-5) {
      EXPECT_TRUE(c.empty());
    }
    if (sph) expect_swap_symmetric(sphere(r), pc, h.shape(), ph);
    else expect_swap_symmetric(capsule(r, hh), pc, h.shape(), ph);
  }
  EXPECT_GT(apart, 30);
  EXPECT_GT(crossing, 30);
}

// ---- scale, determinism, batches ------------------------------------------------------------

struct Scene {
  std::vector<ShapeView> a, b;
  std::vector<Pose> pa, pb;
  void add(const ShapeView& x, const Pose& px, const ShapeView& y, const Pose& py) {
    a.push_back(x), pa.push_back(px), b.push_back(y), pb.push_back(py);
  }
};

Scene overlapping_scene(const Catalogue& cat, uint32_t seed) {
  Scene s;
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 0.9);
  for (size_t i = 0; i < cat.shapes.size(); ++i)
    for (size_t j = 0; j < cat.shapes.size(); ++j) {
      const bool pi = cat.shapes[i].type == ShapeType::plane, pj = cat.shapes[j].type == ShapeType::plane;
      const double reach = (pi ? 0 : cat.radius[i]) + (pj ? 0 : cat.radius[j]);
      for (int k = 0; k < 10; ++k) {
        const Pose pa = pi ? Pose{} : pose_at(Vector3d(0.2, 0.1, pj ? reach * u(rng) : 0.0), random_rotation(rng));
        const Pose pb = pj ? Pose{} : pose_at(pi ? Vector3d(0, 0, reach * u(rng)) : random_direction(rng) * reach * u(rng), random_rotation(rng));
        s.add(cat.shapes[i], pa, cat.shapes[j], pb);
      }
    }
  return s;
}

TEST(NarrowPhase, ScaleIsHonoured) {
  Catalogue cat;
  const Scene s = overlapping_scene(cat, 17);
  int compared = 0;
  for (size_t k = 0; k < s.a.size(); ++k) {
    Pose pa = s.pa[k], pb = s.pb[k];
    const auto one = run(s.a[k], pa, s.b[k], pb, 0.0f);
    for (Pose* p : {&pa, &pb}) {
      for (float& x : p->position) x *= 2;
      p->scale = 2;
    }
    const auto two = run(s.a[k], pa, s.b[k], pb, 0.0f);
    ASSERT_EQ(one.size(), two.size()) << k;
    for (size_t i = 0; i < one.size(); ++i, ++compared) {
      EXPECT_NEAR(two[i].penetration, 2 * one[i].penetration, 1e-5) << k;
      expect_near3(P(two[i]), 2 * P(one[i]), 2e-5);
      expect_near3(N(two[i]), N(one[i]), 1e-5);
    }
  }
  EXPECT_GT(compared, 300);
  // A plane's offset scales too (its pose's position and orientation are ignored).
  const auto one = run(sphere(0.5f), pose_at({0, 0, 0.7}), plane({0, 0, 1}, 0.3f), Pose{});
  const auto two = run(sphere(0.5f), pose_at({0, 0, 1.4}, Quaterniond::Identity(), 2), plane({0, 0, 1}, 0.3f),
                       pose_at({5, 5, 5}, rot(1, {1, 0, 0}), 2));
  ASSERT_EQ(one.size(), 1u);
  ASSERT_EQ(two.size(), 1u);
  EXPECT_NEAR(one[0].penetration, 0.1, 1e-6);
  EXPECT_NEAR(two[0].penetration, 0.2, 1e-6);
}

TEST(NarrowPhase, Deterministic) {
  Catalogue cat;
  const Scene s = overlapping_scene(cat, 23);
  std::vector<std::vector<ContactPoint>> first, again;
  for (size_t k = 0; k < s.a.size(); ++k) first.push_back(run(s.a[k], s.pa[k], s.b[k], s.pb[k]));
  for (size_t k = s.a.size(); k-- > 0;) again.push_back(run(s.a[k], s.pa[k], s.b[k], s.pb[k]));
  std::reverse(again.begin(), again.end());
  // The same hulls copied elsewhere in memory give the same bits too.
  const Catalogue other;
  for (size_t k = 0; k < s.a.size(); ++k) {
    EXPECT_TRUE(same_bits(first[k], again[k])) << k;
    ShapeView a = s.a[k], b = s.b[k];
    if (a.type == ShapeType::hull) a = a.hull.num_vertices == 20 ? other.dod.shape() : other.tet.shape();
    if (b.type == ShapeType::hull) b = b.hull.num_vertices == 20 ? other.dod.shape() : other.tet.shape();
    EXPECT_TRUE(same_bits(first[k], run(a, s.pa[k], b, s.pb[k]))) << k;
  }
}

TEST(NarrowPhase, BatchEqualsPerPair) {
  Catalogue cat;
  const Scene s = overlapping_scene(cat, 29);
  std::vector<ShapeView> shapes;
  std::vector<Pose> poses;
  std::vector<NarrowPair> pairs;
  for (size_t k = 0; k < s.a.size(); ++k) {
    pairs.push_back({int32_t(shapes.size()), int32_t(shapes.size() + 1)});
    shapes.push_back(s.a[k]), shapes.push_back(s.b[k]), poses.push_back(s.pa[k]), poses.push_back(s.pb[k]);
  }
  std::vector<ContactPoint> want;
  std::vector<int32_t> want_pair;
  for (size_t k = 0; k < pairs.size(); ++k)
    for (const auto& c : run(s.a[k], s.pa[k], s.b[k], s.pb[k])) want.push_back(c), want_pair.push_back(int32_t(k));
  std::vector<ContactPoint> out(4 * pairs.size());
  std::vector<int32_t> pair_of(out.size(), -1);
  const int n = collide_batch(shapes.data(), poses.data(), pairs.data(), int(pairs.size()), kMargin, out.data(),
                              pair_of.data(), int(out.size()));
  ASSERT_EQ(n, int(want.size()));
  out.resize(n), pair_of.resize(n);
  EXPECT_TRUE(same_bits(out, want));
  EXPECT_EQ(pair_of, want_pair);
  // A short buffer: whole manifolds only, in order, up to the first that does not fit.
  const int capacity = n / 2 + 1;
  std::vector<ContactPoint> part(capacity);
  const int m = collide_batch(shapes.data(), poses.data(), pairs.data(), int(pairs.size()), kMargin, part.data(),
                              nullptr, capacity);
  ASSERT_LE(m, capacity);
  ASSERT_GT(m, capacity - kMaxManifoldPoints);
  EXPECT_EQ(std::memcmp(part.data(), want.data(), m * sizeof(ContactPoint)), 0);
  EXPECT_TRUE(m == n || want_pair[m] != want_pair[m - 1]) << "a manifold was split";
}

TEST(NarrowPhase, BadInputGivesNothing) {
  // Hulls beyond the bounds, unknown types, and NaN poses: no contact, no crash.
  Catalogue cat;
  std::vector<float> many(3 * (kMaxHullVertices + 1), 0.0f);
  ShapeView big = cat.dod.shape();
  big.hull.num_vertices = kMaxHullVertices + 1, big.hull.vertices = many.data();
  for (const auto& s : cat.shapes) EXPECT_TRUE(run(s, Pose{}, big, Pose{}).empty());
  ShapeView unknown = sphere(1);
  unknown.type = ShapeType(7);
  EXPECT_TRUE(run(unknown, Pose{}, sphere(1), Pose{}).empty());
  Pose nan = Pose{};
  nan.position[1] = std::nanf("");
  for (const auto& a : cat.shapes)
    for (const auto& b : cat.shapes)
      for (const auto& c : run(a, nan, b, Pose{}))
        for (int k = 0; k < 3; ++k) EXPECT_FALSE(std::isnan(c.normal[k])) << "a NaN pose may give nothing, not NaN";
}

TEST(NarrowPhase, HullValidation) {
  EXPECT_TRUE(hull_supported(box_hull(1, 2, 3).shape().hull));
  EXPECT_TRUE(hull_supported(tetrahedron(1).shape().hull));
  EXPECT_TRUE(hull_supported(dodecahedron(1).shape().hull));
  TestHull missing_edge = tetrahedron(1);
  missing_edge.edges.resize(10);
  EXPECT_FALSE(hull_supported(missing_edge.shape().hull));
  TestHull clockwise = box_hull(1, 1, 1);
  std::reverse(clockwise.face_vertices.begin(), clockwise.face_vertices.begin() + 4);
  EXPECT_FALSE(hull_supported(clockwise.shape().hull));
  TestHull inward = tetrahedron(1);
  for (int k = 0; k < 4; ++k) inward.planes[k] = -inward.planes[k];
  EXPECT_FALSE(hull_supported(inward.shape().hull));
}

}  // namespace
