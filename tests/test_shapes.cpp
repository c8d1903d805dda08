// Shape dictionary, convex hulls and mass properties: closed forms and independent numerical
// integration for the masses, structural invariants for the hulls, refusals with clear
// messages, stable views, and bounding boxes under rotation.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstring>
#include <functional>
#include <limits>
#include <random>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "runtime/ppe/convex_hull.h"
#include "runtime/ppe/mass_properties.h"
#include "runtime/ppe/shapes.h"

using namespace cellphys::ppe;
using cellphys::spu::HullView;
using cellphys::spu::Pose;
using cellphys::spu::ShapeType;
using Eigen::Matrix3d;
using Eigen::Vector3d;

namespace {

constexpr double kPi = 3.14159265358979323846;

Matrix3d tensor(const double I[6]) {
  Matrix3d m;
  m << I[0], I[3], I[4], I[3], I[1], I[5], I[4], I[5], I[2];
  return m;
}

Vector3d vertex(const HullView& h, int i) {
  return {h.vertices[3 * i], h.vertices[3 * i + 1], h.vertices[3 * i + 2]};
}

std::vector<float> box_corners(double a, double b, double c, const Matrix3d& R = Matrix3d::Identity(),
                               const Vector3d& t = Vector3d::Zero()) {
  std::vector<float> p;
  for (int i = 0; i < 8; ++i) {
    const Vector3d v = R * Vector3d((i & 1) ? a : -a, (i & 2) ? b : -b, (i & 4) ? c : -c) + t;
    p.insert(p.end(), {float(v.x()), float(v.y()), float(v.z())});
  }
  return p;
}

std::vector<float> fibonacci_sphere(int n, double r) {
  std::vector<float> p;
  const double golden = kPi * (3.0 - std::sqrt(5.0));
  for (int i = 0; i < n; ++i) {
    const double z = 1.0 - 2.0 * (i + 0.5) / n, rho = std::sqrt(1.0 - z * z), phi = golden * i;
    p.insert(p.end(), {float(r * rho * std::cos(phi)), float(r * rho * std::sin(phi)), float(r * z)});
  }
  return p;
}

std::string message_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const ShapeError& e) {
    return e.what();
  }
  return "(no ShapeError)";
}

bool contains(const std::string& s, const std::string& part) { return s.find(part) != std::string::npos; }

// Every structural promise of the HullView layout; points (in hull coordinates) must be inside.
void expect_valid_hull(const HullView& h, const std::vector<float>& points, const Vector3d& shift, double eps,
                       bool only_corners = true) {
  ASSERT_GE(h.num_vertices, 4);
  ASSERT_GE(h.num_faces, 4);
  EXPECT_EQ(h.face_start[0], 0);
  std::multiset<std::pair<int, int>> directed;
  std::vector<std::vector<int>> faces_of(h.num_vertices);
  for (int f = 0; f < h.num_faces; ++f) {
    const Vector3d n(h.planes[4 * f], h.planes[4 * f + 1], h.planes[4 * f + 2]);
    const double d = h.planes[4 * f + 3];
    EXPECT_NEAR(n.norm(), 1.0, 1e-6) << "face " << f;
    const int s = h.face_start[f], e = h.face_start[f + 1];
    ASSERT_GE(e - s, 3) << "face " << f;
    Vector3d newell = Vector3d::Zero();
    for (int i = s; i < e; ++i) {
      const int a = h.face_vertices[i], b = h.face_vertices[i + 1 < e ? i + 1 : s];
      const int c = h.face_vertices[i + 2 < e ? i + 2 : s + (i + 2 - e)];
      ASSERT_TRUE(a >= 0 && a < h.num_vertices);
      directed.insert({a, b});
      faces_of[a].push_back(f);
      EXPECT_NEAR(n.dot(vertex(h, a)), d, eps) << "face " << f << " vertex " << a << " off its plane";
      // A clockwise turn at b would put it inside the chord a-c; allow only the tolerance.
      const Vector3d turn = (vertex(h, b) - vertex(h, a)).cross(vertex(h, c) - vertex(h, b));
      EXPECT_GT(turn.dot(n) / (vertex(h, c) - vertex(h, a)).norm(), -eps)
          << "face " << f << " turns clockwise at vertex " << b;
      newell += (vertex(h, a) - vertex(h, h.face_vertices[s])).cross(vertex(h, b) - vertex(h, h.face_vertices[s]));
    }
    EXPECT_GT(newell.normalized().dot(n), 0.999) << "face " << f << " loop is not ccw about its normal";
    for (size_t p = 0; p < points.size(); p += 3) {
      const Vector3d x = Vector3d(points[p], points[p + 1], points[p + 2]) - shift;
      EXPECT_LE(n.dot(x), d + eps) << "input point " << p / 3 << " outside face " << f;
    }
  }
  // Closed and consistently oriented: each directed edge once, its reverse once.
  for (const auto& [a, b] : directed) {
    EXPECT_EQ(directed.count({a, b}), 1u);
    EXPECT_EQ(directed.count({b, a}), 1u) << "edge " << a << "-" << b << " has no twin";
  }
  // Edge list: every undirected edge of the faces exactly once.
  std::set<std::pair<int, int>> listed;
  for (int i = 0; i < h.num_edges; ++i) {
    const int a = h.edges[2 * i], b = h.edges[2 * i + 1];
    EXPECT_TRUE(directed.count({a, b}) == 1 && directed.count({b, a}) == 1) << "edge " << i;
    EXPECT_TRUE(listed.insert({std::min(a, b), std::max(a, b)}).second) << "edge " << i << " listed twice";
  }
  EXPECT_EQ(listed.size() * 2, directed.size());
  EXPECT_EQ(h.num_vertices - h.num_edges + h.num_faces, 2) << "Euler";
  // Only corners: the face normals at each vertex span 3-D.
  for (int v = 0; only_corners && v < h.num_vertices; ++v) {
    ASSERT_GE(faces_of[v].size(), 3u) << "vertex " << v;
    double best = 0;
    const auto& F = faces_of[v];
    for (size_t i = 0; i < F.size(); ++i)
      for (size_t j = i + 1; j < F.size(); ++j)
        for (size_t k = j + 1; k < F.size(); ++k) {
          Matrix3d m;
          for (int c = 0; c < 3; ++c) m(0, c) = h.planes[4 * F[i] + c], m(1, c) = h.planes[4 * F[j] + c],
                                      m(2, c) = h.planes[4 * F[k] + c];
          best = std::max(best, std::fabs(m.determinant()));
        }
    EXPECT_GT(best, 1e-9) << "vertex " << v << " is not a corner";
  }
}

void expect_valid_hull(const ConvexHull& c, const std::vector<float>& points, bool only_corners = true) {
  expect_valid_hull(c.view(), points, Vector3d::Zero(), 4 * c.tolerance, only_corners);
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Mass properties

TEST(MassProperties, SphereMatchesClosedForm) {
  ShapeDictionary d;
  const uint32_t s = d.add_sphere(0.7f);
  const MassProperties m = mass_properties_from_density(d, s, 1.0f, 3.0f);
  const double r = double(0.7f), V = 4.0 / 3.0 * kPi * r * r * r;
  EXPECT_NEAR(m.volume, V, 1e-12);
  EXPECT_NEAR(m.mass, 3.0 * V, 1e-12);
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(m.inertia[k], 0.4 * 3.0 * V * r * r, 1e-12);
  for (int k = 3; k < 6; ++k) EXPECT_EQ(m.inertia[k], 0.0);
  for (double c : m.center_of_mass) EXPECT_EQ(c, 0.0);
}

TEST(MassProperties, BoxMatchesClosedFormWithHalfExtents) {
  ShapeDictionary d;
  const float he[3] = {0.5f, 1.0f, 1.5f};
  const MassProperties m = mass_properties_from_density(d, d.add_box(he), 1.0f, 2.0f);
  const double V = 8 * 0.5 * 1.0 * 1.5, M = 2 * V;
  EXPECT_NEAR(m.volume, V, 1e-12);
  EXPECT_NEAR(m.inertia[0], M / 3 * (1.0 + 2.25), 1e-12);
  EXPECT_NEAR(m.inertia[1], M / 3 * (0.25 + 2.25), 1e-12);
  EXPECT_NEAR(m.inertia[2], M / 3 * (0.25 + 1.0), 1e-12);
  for (int k = 3; k < 6; ++k) EXPECT_EQ(m.inertia[k], 0.0);
}

TEST(MassProperties, CapsuleMatchesVoxelIntegrationWithinHalfPercent) {
  const float r = 0.5f, h = 0.75f;
  ShapeDictionary d;
  const MassProperties m = mass_properties_from_density(d, d.add_capsule(r, h), 1.0f, 1.0f);
  // Midpoint rule over one octant (the capsule is symmetric in x, y and z).
  const int nx = 200, nz = 500;
  const double dx = r / double(nx), dz = (h + r) / double(nz), cell = dx * dx * dz;
  double V = 0, Ixx = 0, Izz = 0;
  for (int k = 0; k < nz; ++k) {
    const double z = (k + 0.5) * dz, zc = std::max(0.0, z - h), rr = double(r) * r - zc * zc;
    if (rr <= 0) continue;
    for (int i = 0; i < nx; ++i) {
      const double x = (i + 0.5) * dx;
      for (int j = 0; j < nx; ++j) {
        const double y = (j + 0.5) * dx;
        if (x * x + y * y > rr) continue;
        V += cell, Ixx += cell * (y * y + z * z), Izz += cell * (x * x + y * y);
      }
    }
  }
  V *= 8, Ixx *= 8, Izz *= 8;
  EXPECT_NEAR(m.volume / V, 1.0, 0.005);
  EXPECT_NEAR(m.inertia[0] / Ixx, 1.0, 0.005);
  EXPECT_NEAR(m.inertia[1] / Ixx, 1.0, 0.005);
  EXPECT_NEAR(m.inertia[2] / Izz, 1.0, 0.005);
  // And the closed form itself: a zero-length capsule would be a sphere; a long one, a rod.
  const double vc = 2 * kPi * 0.25 * 0.75, vs = 4.0 / 3.0 * kPi * 0.125;
  EXPECT_NEAR(m.volume, vc + vs, 1e-12);
}

TEST(MassProperties, HullOfBoxCornersEqualsBox) {
  ShapeDictionary d;
  const float he[3] = {0.5f, 1.0f, 1.5f};
  const uint32_t box = d.add_box(he);
  const std::vector<float> pts = box_corners(0.5, 1.0, 1.5);
  const uint32_t hull = d.add_hull(pts.data(), 8);
  const MassProperties a = mass_properties_from_density(d, box, 1.3f, 2.0f);
  const MassProperties b = mass_properties_from_density(d, hull, 1.3f, 2.0f);
  EXPECT_NEAR(b.volume / a.volume, 1.0, 1e-5);
  EXPECT_NEAR(b.mass / a.mass, 1.0, 1e-5);
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(b.inertia[k] / a.inertia[k], 1.0, 1e-5);
  for (int k = 3; k < 6; ++k) EXPECT_NEAR(b.inertia[k], 0.0, 1e-5 * a.inertia[0]);
  for (double c : b.center_of_mass) EXPECT_NEAR(c, 0.0, 1e-6);
}

TEST(MassProperties, HullIsRecentredOnItsCentreOfMassAndReportsTheShift) {
  ShapeDictionary d;
  const std::vector<float> pts = box_corners(0.5, 1.0, 1.5, Matrix3d::Identity(), Vector3d(3, -2, 5));
  HullInfo info;
  const uint32_t i = d.add_hull(pts.data(), 8, &info);
  EXPECT_NEAR(info.shift[0], 3.0, 1e-6);
  EXPECT_NEAR(info.shift[1], -2.0, 1e-6);
  EXPECT_NEAR(info.shift[2], 5.0, 1e-6);
  EXPECT_EQ(d.hull_info(i).shift[2], info.shift[2]);
  EXPECT_EQ(info.num_input_points, 8);
  const MassProperties m = mass_properties_from_density(d, i, 1.0f, 1.0f);
  for (double c : m.center_of_mass) EXPECT_NEAR(c, 0.0, 1e-6);
  float lo[3], hi[3];
  d.local_aabb(i, 1.0f, lo, hi);
  EXPECT_NEAR(lo[0], -0.5, 1e-6);
  EXPECT_NEAR(hi[2], 1.5, 1e-6);
}

TEST(MassProperties, HullOfPointsOnSphereApproachesSphereWithinTwoPercent) {
  ShapeDictionary d(HullLimits{4096, 1024});
  const std::vector<float> pts = fibonacci_sphere(500, 1.0);
  const MassProperties h = mass_properties_from_density(d, d.add_hull(pts.data(), 500), 1.0f, 1.0f);
  const MassProperties s = mass_properties_from_density(d, d.add_sphere(1.0f), 1.0f, 1.0f);
  EXPECT_LT(h.volume, s.volume);  // inscribed
  EXPECT_NEAR(h.volume / s.volume, 1.0, 0.02);
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(h.inertia[k] / s.inertia[k], 1.0, 0.02);
  for (int k = 3; k < 6; ++k) EXPECT_NEAR(h.inertia[k] / s.inertia[0], 0.0, 0.002);
}

TEST(MassProperties, RotatedBoxHullGivesRotatedTensorWithCorrectProductSigns) {
  const Matrix3d R = Eigen::Quaterniond(0.9, 0.3, -0.2, 0.4).normalized().toRotationMatrix();
  ShapeDictionary d;
  const float he[3] = {1.0f, 0.5f, 0.25f};
  const MassProperties box = mass_properties_from_density(d, d.add_box(he), 1.0f, 1.0f);
  const std::vector<float> pts = box_corners(1.0, 0.5, 0.25, R);
  const MassProperties hull = mass_properties_from_density(d, d.add_hull(pts.data(), 8), 1.0f, 1.0f);
  const Matrix3d expect = R * tensor(box.inertia) * R.transpose();
  const Matrix3d got = tensor(hull.inertia);
  EXPECT_LT((got - expect).norm(), 1e-5 * expect.norm()) << got << "\n\n" << expect;

  // Sign convention: a rod along x turned +45 degrees about z puts its mass where x y > 0, so
  // Ixy = -integral(x y) < 0, and equals cos sin (Ixx - Iyy) of the unrotated rod.
  const Matrix3d Rz = Eigen::AngleAxisd(kPi / 4, Vector3d::UnitZ()).toRotationMatrix();
  const float rod[3] = {2.0f, 0.5f, 0.5f};
  const MassProperties body = mass_properties_from_density(d, d.add_box(rod), 1.0f, 1.0f);
  const std::vector<float> q = box_corners(2.0, 0.5, 0.5, Rz);
  const MassProperties turned = mass_properties_from_density(d, d.add_hull(q.data(), 8), 1.0f, 1.0f);
  EXPECT_LT(turned.inertia[3], 0.0);
  EXPECT_NEAR(turned.inertia[3], 0.5 * (body.inertia[0] - body.inertia[1]), 1e-5 * body.inertia[1]);
  EXPECT_NEAR(turned.inertia[4], 0.0, 1e-5 * body.inertia[1]);
  EXPECT_NEAR(turned.inertia[5], 0.0, 1e-5 * body.inertia[1]);
}

TEST(MassProperties, ScaleMultipliesVolumeByCubeAndInertiaByFifthPower) {
  ShapeDictionary d;
  const float he[3] = {0.3f, 0.4f, 0.5f};
  const std::vector<float> pts = box_corners(1.0, 0.5, 0.25, Eigen::AngleAxisd(0.3, Vector3d(1, 2, 3).normalized()).toRotationMatrix());
  const uint32_t ids[4] = {d.add_sphere(0.5f), d.add_capsule(0.25f, 0.6f), d.add_box(he), d.add_hull(pts.data(), 8)};
  const double s = 2.5;
  for (uint32_t i : ids) {
    const MassProperties a = mass_properties_from_density(d, i, 1.0f, 7.0f);
    const MassProperties b = mass_properties_from_density(d, i, float(s), 7.0f);
    EXPECT_NEAR(b.volume / a.volume, s * s * s, 1e-9) << "shape " << i;
    for (int k = 0; k < 6; ++k)
      EXPECT_NEAR(b.inertia[k], a.inertia[k] * std::pow(s, 5), 1e-9 * std::fabs(b.inertia[0])) << "shape " << i;
  }
}

TEST(MassProperties, GivenMassScalesDensityToMatch) {
  ShapeDictionary d;
  const uint32_t c = d.add_capsule(0.3f, 0.8f);
  const MassProperties byd = mass_properties_from_density(d, c, 1.5f, 1.0f);
  const MassProperties bym = mass_properties_from_mass(d, c, 1.5f, 12.0f);
  EXPECT_DOUBLE_EQ(bym.mass, 12.0);
  EXPECT_NEAR(bym.volume, byd.volume, 1e-12);
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(bym.inertia[k], byd.inertia[k] * 12.0 / byd.mass, 1e-9);
}

TEST(MassProperties, BadInputAndPlanesAreRefused) {
  ShapeDictionary d;
  const uint32_t s = d.add_sphere(1.0f);
  const float n[3] = {0, 0, 1};
  const uint32_t p = d.add_plane(n, 0.0f);
  const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
  EXPECT_TRUE(contains(message_of([&] { mass_properties_from_density(d, s, 1.0f, 0.0f); }), "density"));
  EXPECT_TRUE(contains(message_of([&] { mass_properties_from_density(d, s, 1.0f, -2.0f); }), "density"));
  EXPECT_TRUE(contains(message_of([&] { mass_properties_from_density(d, s, 1.0f, nan); }), "density"));
  EXPECT_TRUE(contains(message_of([&] { mass_properties_from_density(d, s, 1.0f, inf); }), "density"));
  EXPECT_TRUE(contains(message_of([&] { mass_properties_from_density(d, s, 0.0f, 1.0f); }), "scale"));
  EXPECT_TRUE(contains(message_of([&] { mass_properties_from_density(d, s, nan, 1.0f); }), "scale"));
  EXPECT_TRUE(contains(message_of([&] { mass_properties_from_mass(d, s, 1.0f, -1.0f); }), "mass must be positive"));
  EXPECT_TRUE(contains(message_of([&] { mass_properties_from_mass(d, s, 1.0f, 0.0f); }), "sphere"));
  EXPECT_TRUE(contains(message_of([&] { mass_properties_from_density(d, p, 1.0f, 1.0f); }), "plane"));
  EXPECT_TRUE(contains(message_of([&] { mass_properties_from_mass(d, p, 1.0f, 1.0f); }), "plane"));
}

// ---------------------------------------------------------------------------------------------
// Convex hull

TEST(ConvexHull, NoisyCubeCloudKeepsExactlyTheEightCorners) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> inner(-0.95f, 0.95f), face(-0.9f, 0.9f);
  std::vector<float> pts = box_corners(1, 1, 1);
  const std::vector<float> corners = pts;
  pts.insert(pts.end(), corners.begin(), corners.end());  // duplicates
  for (int i = 0; i < 300; ++i) pts.insert(pts.end(), {inner(rng), inner(rng), inner(rng)});
  const float noise[3] = {-1e-7f, 0.0f, 1e-7f};
  for (int axis = 0; axis < 3; ++axis)
    for (float side : {-1.0f, 1.0f})
      for (int i = 0; i < 30; ++i) {
        float p[3] = {face(rng), face(rng), face(rng)};
        p[axis] = side + noise[rng() % 3];
        pts.insert(pts.end(), p, p + 3);
      }
  for (int axis = 0; axis < 3; ++axis)  // points on the edges
    for (float t : {0.0f, 0.3f, -0.7f}) {
      float p[3] = {1.0f, -1.0f, 1.0f};
      p[axis] = t;
      pts.insert(pts.end(), p, p + 3);
    }
  // Shuffle points (as triples) so corners are not first.
  std::vector<int> order(pts.size() / 3);
  for (size_t i = 0; i < order.size(); ++i) order[i] = int(i);
  std::shuffle(order.begin(), order.end(), rng);
  std::vector<float> cloud;
  for (int i : order) cloud.insert(cloud.end(), pts.begin() + 3 * i, pts.begin() + 3 * i + 3);

  const ConvexHull h = compute_convex_hull(cloud.data(), int(cloud.size() / 3));
  ASSERT_EQ(h.num_vertices(), 8);
  EXPECT_EQ(h.num_faces(), 6);
  EXPECT_EQ(h.num_edges(), 12);
  std::set<std::vector<float>> got, want;
  for (int v = 0; v < 8; ++v) got.insert({h.vertices[3 * v], h.vertices[3 * v + 1], h.vertices[3 * v + 2]});
  for (int v = 0; v < 8; ++v) want.insert({corners[3 * v], corners[3 * v + 1], corners[3 * v + 2]});
  EXPECT_EQ(got, want);
  for (int f = 0; f < 6; ++f) EXPECT_EQ(h.face_start[f + 1] - h.face_start[f], 4);
  expect_valid_hull(h, cloud);
}

TEST(ConvexHull, NearDuplicateCornersBecomeOneVertexEach) {
  // Clusters of copies jittered by up to 1e-6 (below the tolerance, ~3e-6 here) in random
  // directions around the six corners of an octahedron: no tiny facets or sliver edges.
  std::mt19937 rng(2);
  std::uniform_real_distribution<float> jitter(-1e-6f, 1e-6f);
  const float corners[6][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {-0.7f, 0, 0}, {0, -0.7f, 0}, {0, 0, -0.7f}};
  std::vector<float> pts;
  for (int copy = 0; copy < 12; ++copy)
    for (const auto& c : corners)
      for (int k = 0; k < 3; ++k) pts.push_back(c[k] + jitter(rng));
  const ConvexHull h = compute_convex_hull(pts.data(), int(pts.size() / 3));
  EXPECT_EQ(h.num_vertices(), 6);
  EXPECT_EQ(h.num_faces(), 8);
  EXPECT_EQ(h.num_edges(), 12);
  expect_valid_hull(h, pts);
}

TEST(ConvexHull, VerticesOfASampledBoxSurfaceStickOutOfTheOthersHull) {
  // Points sampled on the faces of a rotated box away from the origin: the hull cuts its edges
  // and corners, and float rounding puts points a hair off each face, which leaves shallow
  // tents unless they are removed. A vertex is dropped when it is within the tolerance of the
  // others' hull, so every vertex left must stick out of it (by nearly the tolerance at least:
  // removal is also refused when it would leave a point outside by more than the tolerance).
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const Matrix3d R = Eigen::AngleAxisd(1.7, Vector3d(1, -2, 0.5).normalized()).toRotationMatrix();
  std::vector<float> pts;
  for (int i = 0; i < 1500; ++i) {
    Vector3d v(u(rng), u(rng), u(rng));
    v /= v.lpNorm<Eigen::Infinity>();
    v = R * v.cwiseProduct(Vector3d(1.0, 0.6, 0.3)) + Vector3d(100, -100, 50);
    pts.insert(pts.end(), {float(v.x()), float(v.y()), float(v.z())});
  }
  const ConvexHull h = compute_convex_hull(pts.data(), 1500, HullLimits{4096, 4096});
  expect_valid_hull(h, pts, false);
  for (int v = 0; v < h.num_vertices(); ++v) {
    std::vector<float> others;
    for (int w = 0; w < h.num_vertices(); ++w)
      if (w != v) others.insert(others.end(), &h.vertices[3 * w], &h.vertices[3 * w + 3]);
    const ConvexHull rest = compute_convex_hull(others.data(), int(others.size() / 3), HullLimits{4096, 4096});
    const Vector3d p(h.vertices[3 * v], h.vertices[3 * v + 1], h.vertices[3 * v + 2]);
    double out = -1.0;
    for (int f = 0; f < rest.num_faces(); ++f)
      out = std::max(out, Vector3d(rest.planes[4 * f], rest.planes[4 * f + 1], rest.planes[4 * f + 2]).dot(p) -
                              rest.planes[4 * f + 3]);
    EXPECT_GT(out, 0.5 * h.tolerance) << "vertex " << v << " hardly sticks out of the others' hull";
  }
}

TEST(ConvexHull, CubeGridGivesSixQuadFacesEightVerticesTwelveEdges) {
  std::vector<float> pts;
  for (int i = -1; i <= 1; ++i)
    for (int j = -1; j <= 1; ++j)
      for (int k = -1; k <= 1; ++k) pts.insert(pts.end(), {float(i), float(j), float(k)});
  const ConvexHull h = compute_convex_hull(pts.data(), 27);
  EXPECT_EQ(h.num_vertices(), 8);
  EXPECT_EQ(h.num_faces(), 6);
  EXPECT_EQ(h.num_edges(), 12);
  for (int f = 0; f < h.num_faces(); ++f) EXPECT_EQ(h.face_start[f + 1] - h.face_start[f], 4);
  expect_valid_hull(h, pts);
}

TEST(ConvexHull, RandomThousandPointCloudsGiveValidClosedHulls) {
  for (unsigned seed = 1; seed <= 4; ++seed) {
    std::mt19937 rng(seed);
    std::normal_distribution<float> gauss(0.0f, 1.0f);
    std::uniform_real_distribution<float> uni(-1.0f, 1.0f);
    std::vector<float> cube, normal, ball;
    for (int i = 0; i < 1000; ++i) {
      cube.insert(cube.end(), {uni(rng), uni(rng), 0.25f * uni(rng)});
      normal.insert(normal.end(), {gauss(rng) + 40.0f, gauss(rng), 3.0f * gauss(rng)});
      float p[3];
      do {
        for (float& c : p) c = uni(rng);
      } while (p[0] * p[0] + p[1] * p[1] + p[2] * p[2] > 1.0f);
      ball.insert(ball.end(), p, p + 3);
    }
    for (const auto* pts : {&cube, &normal, &ball}) {
      SCOPED_TRACE("seed " + std::to_string(seed));
      const ConvexHull h = compute_convex_hull(pts->data(), 1000);
      expect_valid_hull(h, *pts);
    }
  }
  // All points extreme, beyond the default vertex limit.
  const std::vector<float> sphere = fibonacci_sphere(1000, 2.0);
  const ConvexHull h = compute_convex_hull(sphere.data(), 1000, HullLimits{4096, 2000});
  EXPECT_EQ(h.num_vertices(), 1000);
  expect_valid_hull(h, sphere);
}

TEST(ConvexHull, RoundedGridsWithManyCoplanarPointsStayValid) {
  // Lattice points in a ball: many exactly coplanar and collinear subsets, the worst case
  // for a hull without exact predicates.
  std::vector<float> pts;
  for (int i = -6; i <= 6; ++i)
    for (int j = -6; j <= 6; ++j)
      for (int k = -6; k <= 6; ++k)
        if (i * i + j * j + k * k <= 36) pts.insert(pts.end(), {0.1f * i, 0.1f * j, 0.1f * k});
  const ConvexHull h = compute_convex_hull(pts.data(), int(pts.size() / 3));
  expect_valid_hull(h, pts);
  // A cube far from the origin, where float rounding dominates the tolerance.
  const std::vector<float> far = box_corners(1, 2, 3, Matrix3d::Identity(), Vector3d(1e4, -3e4, 2e4));
  const ConvexHull f = compute_convex_hull(far.data(), 8);
  EXPECT_EQ(f.num_faces(), 6);
  expect_valid_hull(f, far);
}

TEST(ConvexHull, SameInputGivesIdenticalOutput) {
  std::mt19937 rng(11);
  std::normal_distribution<float> g(0.0f, 1.0f);
  std::vector<float> pts;
  for (int i = 0; i < 2000; ++i) pts.push_back(g(rng));
  const ConvexHull a = compute_convex_hull(pts.data(), 2000 / 3);
  const ConvexHull b = compute_convex_hull(pts.data(), 2000 / 3);
  EXPECT_EQ(a.vertices, b.vertices);
  EXPECT_EQ(a.planes, b.planes);
  EXPECT_EQ(a.face_start, b.face_start);
  EXPECT_EQ(a.face_vertices, b.face_vertices);
  EXPECT_EQ(a.edges, b.edges);
  EXPECT_TRUE(std::is_sorted(a.source.begin(), a.source.end()));  // vertices in input order
}

TEST(ConvexHull, DictionaryHullIsValidAndContainsTheShiftedInput) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  std::vector<float> pts;
  for (int i = 0; i < 600; ++i) pts.insert(pts.end(), {u(rng) + 5.0f, 2.0f * u(rng), u(rng) * u(rng)});
  ShapeDictionary d;
  HullInfo info;
  const uint32_t i = d.add_hull(pts.data(), 600, &info);
  EXPECT_EQ(d.type(i), ShapeType::hull);
  const HullView& h = d.view(i).hull;
  EXPECT_EQ(h.num_vertices, info.num_vertices);
  EXPECT_EQ(h.num_faces, info.num_faces);
  EXPECT_EQ(h.num_edges, info.num_edges);
  expect_valid_hull(h, pts, Vector3d(info.shift[0], info.shift[1], info.shift[2]), 2e-5);
}

// ---------------------------------------------------------------------------------------------
// Refusals

TEST(ShapeDictionary, DegenerateHullsAreRefusedWithTheReasonAndNothingAdded) {
  ShapeDictionary d;
  d.add_sphere(1.0f);
  auto refused = [&](const std::vector<float>& p, const std::string& part) {
    const std::string msg = message_of([&] { d.add_hull(p.data(), int(p.size() / 3)); });
    EXPECT_TRUE(contains(msg, "hull")) << msg;
    EXPECT_TRUE(contains(msg, part)) << msg;
    EXPECT_EQ(d.size(), 1u);
  };
  refused({0, 0, 0, 1, 0, 0, 0, 1, 0}, "at least 4");
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  std::vector<float> plane, line, same;
  for (int i = 0; i < 100; ++i) {
    const float x = u(rng), y = u(rng), t = u(rng);
    plane.insert(plane.end(), {x, y, 0.3f * x - 0.7f * y + 2.0f});  // tilted: coplanar up to rounding
    line.insert(line.end(), {1.0f + 0.5f * t, 2.0f - 0.25f * t, 3.0f * t});
    same.insert(same.end(), {0.5f, -1.5f, 2.0f});
  }
  refused(plane, "coplanar");
  refused(line, "collinear");
  refused(same, "coincide");
  std::vector<float> with_nan = box_corners(1, 1, 1);
  with_nan[13] = std::numeric_limits<float>::quiet_NaN();
  refused(with_nan, "not finite");
  std::vector<float> many(3 * 4097, 0.0f);
  for (float& x : many) x = u(rng);
  refused(many, "limit of 4096");
  const std::vector<float> round = fibonacci_sphere(300, 1.0);
  refused(round, "300 vertices, more than the limit of 256");
}

TEST(ShapeDictionary, BadPrimitivesAreRefusedNamingShapeAndNothingAdded) {
  ShapeDictionary d;
  const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
  auto refused = [&](const std::function<void()>& f, const std::string& kind, const std::string& part) {
    const std::string msg = message_of(f);
    EXPECT_TRUE(contains(msg, kind + ":")) << msg;
    EXPECT_TRUE(contains(msg, part)) << msg;
    EXPECT_EQ(d.size(), 0u);
  };
  refused([&] { d.add_sphere(0.0f); }, "sphere", "radius must be positive");
  refused([&] { d.add_sphere(-1.0f); }, "sphere", "radius");
  refused([&] { d.add_sphere(nan); }, "sphere", "radius");
  refused([&] { d.add_sphere(inf); }, "sphere", "finite");
  refused([&] { d.add_capsule(1.0f, 0.0f); }, "capsule", "half height");
  refused([&] { d.add_capsule(nan, 1.0f); }, "capsule", "radius");
  refused([&] { d.add_capsule(1.0f, -inf); }, "capsule", "half height");
  const float flat[3] = {1.0f, 0.0f, 1.0f}, bad[3] = {1.0f, nan, 1.0f};
  refused([&] { d.add_box(flat); }, "box", "half extent y");
  refused([&] { d.add_box(bad); }, "box", "half extent y");
  const float zero[3] = {0, 0, 0}, nn[3] = {0, nan, 1}, up[3] = {0, 0, 1};
  refused([&] { d.add_plane(zero, 1.0f); }, "plane", "normal is zero");
  refused([&] { d.add_plane(nn, 1.0f); }, "plane", "normal is not finite");
  refused([&] { d.add_plane(up, inf); }, "plane", "offset");
  EXPECT_THROW(d.view(0), std::out_of_range);
  const uint32_t s = d.add_sphere(1.0f);
  EXPECT_TRUE(contains(message_of([&] { d.hull_info(s); }), "not a hull"));
  EXPECT_TRUE((std::is_base_of_v<std::invalid_argument, ShapeError>));
}

TEST(ShapeDictionary, PlaneNormalIsNormalisedAndPlaneIsStaticInfinite) {
  ShapeDictionary d;
  const float n[3] = {0.0f, 3.0f, 4.0f};
  const uint32_t p = d.add_plane(n, 2.0f);
  EXPECT_NEAR(d.view(p).normal[1], 0.6, 1e-7);
  EXPECT_NEAR(d.view(p).normal[2], 0.8, 1e-7);
  EXPECT_TRUE(d.is_static_infinite(p));
  EXPECT_FALSE(d.is_static_infinite(d.add_sphere(1.0f)));
  float lo[3], hi[3];
  d.world_aabb(p, Pose{}, lo, hi);
  for (int k = 0; k < 3; ++k) EXPECT_TRUE(std::isinf(lo[k]) && lo[k] < 0 && std::isinf(hi[k]) && hi[k] > 0);
  const float z[3] = {0.0f, 0.0f, 1.0f};
  d.world_aabb(d.add_plane(z, -1.5f), Pose{}, lo, hi);  // ground: solid below z = -1.5
  EXPECT_EQ(hi[2], -1.5f);
  EXPECT_TRUE(std::isinf(lo[2]) && std::isinf(hi[0]) && std::isinf(lo[1]));
}

// ---------------------------------------------------------------------------------------------
// Storage

TEST(ShapeDictionary, HullViewsStayValidAsShapesAreAdded) {
  ShapeDictionary d;
  const std::vector<float> first = fibonacci_sphere(60, 1.0);
  const uint32_t i0 = d.add_hull(first.data(), 60);
  const cellphys::spu::ShapeView* address = &d.view(i0);
  const HullView h = d.view(i0).hull;
  const std::vector<float> verts(h.vertices, h.vertices + 3 * h.num_vertices);
  const std::vector<float> planes(h.planes, h.planes + 4 * h.num_faces);
  const std::vector<int32_t> loops(h.face_vertices, h.face_vertices + h.face_start[h.num_faces]);
  const std::vector<int32_t> edges(h.edges, h.edges + 2 * h.num_edges);
  std::mt19937 rng(9);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  for (int k = 0; k < 100; ++k) {
    std::vector<float> p;
    for (int i = 0; i < 30; ++i) p.push_back(u(rng));
    d.add_hull(p.data(), 10);
    d.add_sphere(0.5f + k);
  }
  ASSERT_EQ(d.size(), 201u);
  EXPECT_EQ(&d.view(i0), address);
  const HullView g = d.view(i0).hull;
  EXPECT_EQ(g.vertices, h.vertices);
  EXPECT_EQ(g.planes, h.planes);
  EXPECT_EQ(g.face_vertices, h.face_vertices);
  EXPECT_EQ(g.edges, h.edges);
  EXPECT_EQ(std::vector<float>(g.vertices, g.vertices + 3 * g.num_vertices), verts);
  EXPECT_EQ(std::vector<float>(g.planes, g.planes + 4 * g.num_faces), planes);
  EXPECT_EQ(std::vector<int32_t>(g.face_vertices, g.face_vertices + g.face_start[g.num_faces]), loops);
  EXPECT_EQ(std::vector<int32_t>(g.edges, g.edges + 2 * g.num_edges), edges);
  // Moving the dictionary keeps them too.
  ShapeDictionary moved = std::move(d);
  EXPECT_EQ(moved.view(i0).hull.vertices, h.vertices);
}

TEST(ShapeDictionary, BytesCountGeometryStored) {
  ShapeDictionary d;
  const float he[3] = {1, 1, 1}, n[3] = {0, 0, 1};
  d.add_sphere(1.0f);
  d.add_capsule(1.0f, 1.0f);
  d.add_box(he);
  d.add_plane(n, 0.0f);
  EXPECT_EQ(d.bytes(), 4u + 8u + 12u + 16u);
  const std::vector<float> cube = box_corners(1, 1, 1);
  const uint32_t h = d.add_hull(cube.data(), 8);
  // 8 vertices, 6 planes, 7 face starts, 24 loop entries, 12 edges.
  EXPECT_EQ(d.bytes(h), 8u * 12 + 6u * 16 + 7u * 4 + 24u * 4 + 12u * 8);
  EXPECT_EQ(d.bytes(), 40u + d.bytes(h));
}

// ---------------------------------------------------------------------------------------------
// Bounding boxes

TEST(ShapeDictionary, WorldAabbOfBoxRotated45AboutZIsAnalytic) {
  ShapeDictionary d;
  const float he[3] = {1.0f, 0.5f, 0.25f};
  const uint32_t box = d.add_box(he);
  const std::vector<float> corners = box_corners(1.0, 0.5, 0.25);
  const uint32_t hull = d.add_hull(corners.data(), 8);
  Pose pose;
  pose.position[0] = 1, pose.position[1] = 2, pose.position[2] = 3;
  pose.orientation[0] = float(std::cos(kPi / 8)), pose.orientation[3] = float(std::sin(kPi / 8));
  pose.scale = 2.0f;
  const double ex = 2.0 * 1.5 / std::sqrt(2.0), ez = 2.0 * 0.25;
  for (uint32_t i : {box, hull}) {
    float lo[3], hi[3];
    d.world_aabb(i, pose, lo, hi);
    EXPECT_NEAR(lo[0], 1 - ex, 1e-5);
    EXPECT_NEAR(hi[0], 1 + ex, 1e-5);
    EXPECT_NEAR(lo[1], 2 - ex, 1e-5);
    EXPECT_NEAR(hi[1], 2 + ex, 1e-5);
    EXPECT_NEAR(lo[2], 3 - ez, 1e-5);
    EXPECT_NEAR(hi[2], 3 + ez, 1e-5);
  }
}

TEST(ShapeDictionary, WorldAabbOfSphereIsCentrePlusScaledRadius) {
  ShapeDictionary d;
  const uint32_t s = d.add_sphere(0.5f);
  Pose pose;
  pose.position[0] = -1, pose.position[1] = 4, pose.position[2] = 0.5f;
  pose.orientation[0] = 0.5f, pose.orientation[1] = 0.5f, pose.orientation[2] = 0.5f, pose.orientation[3] = 0.5f;
  pose.scale = 3.0f;
  float lo[3], hi[3];
  d.world_aabb(s, pose, lo, hi);
  for (int k = 0; k < 3; ++k) {
    EXPECT_FLOAT_EQ(lo[k], pose.position[k] - 1.5f);
    EXPECT_FLOAT_EQ(hi[k], pose.position[k] + 1.5f);
  }
  d.local_aabb(s, 2.0f, lo, hi);
  EXPECT_FLOAT_EQ(lo[0], -1.0f);
  EXPECT_FLOAT_EQ(hi[2], 1.0f);
}

TEST(ShapeDictionary, WorldAabbOfCapsuleLyingAlongX) {
  ShapeDictionary d;
  const uint32_t c = d.add_capsule(0.25f, 1.0f);
  Pose pose;  // 90 degrees about y takes body z to world x
  pose.orientation[0] = float(std::sqrt(0.5)), pose.orientation[2] = float(std::sqrt(0.5));
  float lo[3], hi[3];
  d.world_aabb(c, pose, lo, hi);
  EXPECT_NEAR(lo[0], -1.25, 1e-6);
  EXPECT_NEAR(hi[0], 1.25, 1e-6);
  EXPECT_NEAR(lo[1], -0.25, 1e-6);
  EXPECT_NEAR(hi[1], 0.25, 1e-6);
  EXPECT_NEAR(lo[2], -0.25, 1e-6);
  EXPECT_NEAR(hi[2], 0.25, 1e-6);
  d.local_aabb(c, 1.0f, lo, hi);
  EXPECT_FLOAT_EQ(hi[2], 1.25f);
  EXPECT_FLOAT_EQ(hi[0], 0.25f);
}

TEST(ShapeDictionary, WorldAabbRefusesBadScale) {
  ShapeDictionary d;
  const uint32_t s = d.add_sphere(1.0f);
  Pose pose;
  pose.scale = 0.0f;
  float lo[3], hi[3];
  EXPECT_THROW(d.world_aabb(s, pose, lo, hi), ShapeError);
  EXPECT_THROW(d.local_aabb(s, -1.0f, lo, hi), ShapeError);
}
