// Narrow phase: contact manifolds between convex shapes (see narrow_phase.h for conventions).
//
// Geometry is computed in double from the float inputs and rounded once on output: on a scalar
// core it costs nothing, and it keeps the separating-axis and clipping decisions consistent
// for deep contacts and for bodies far from the origin.
//
// File layout: vector helpers; the contact sink; sphere, capsule and plane pairs (closed
// forms); sphere-box; polytopes (boxes and hulls in world space); a point or segment against
// a polytope; a polytope against a plane; polytope against polytope (separating axes,
// clipping, reduction); dispatch in one canonical order.
#include "runtime/spu/narrow_phase.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

#include "runtime/base/vec3.h"
#include "runtime/spu/surface_tree.h"

namespace cellphys::spu {
namespace {

// ---- tolerances -----------------------------------------------------------------------------

// A segment or face within ~2.6 degrees of lying flat on a face gets a 2-point (segment) or
// clipped (face) contact, and two capsule cores that close to parallel get 2 points: one
// point would let a resting capsule rock about it.
constexpr double kParallelCos = 0.999;
constexpr double kParallelSin2 = 1.0 - kParallelCos * kParallelCos;
// Edge pairs closer to parallel than this (sine of the angle) give no axis: their cross
// product is noise, and the face axes already cover that configuration.
constexpr double kEdgeParallelSin2 = 5e-3 * 5e-3;
// Axis choice bias, for frame-to-frame stability of the manifold: the reference face is on b
// only if b's best face is shallower than a's by 2% + the absolute tolerance, and an edge
// axis wins only if shallower than the best face by 5% + the absolute tolerance. The absolute
// tolerance is this fraction of the smaller shape's size (scale-invariant).
constexpr double kFaceRel = 0.02;
constexpr double kEdgeRel = 0.05;
constexpr double kBiasAbs = 5e-4;

constexpr double kInf = std::numeric_limits<double>::infinity();

// ---- vectors --------------------------------------------------------------------------------

inline double clamp01(double t) { return t < 0.0 ? 0.0 : (t > 1.0 ? 1.0 : t); }

/// A deterministic unit vector perpendicular to u (any, if u is zero).
Vec3d any_perpendicular(const Vec3d& u) {
  const double ax = std::fabs(u.x), ay = std::fabs(u.y), az = std::fabs(u.z);
  const Vec3d e = (ax <= ay && ax <= az) ? Vec3d{1, 0, 0} : (ay <= az ? Vec3d{0, 1, 0} : Vec3d{0, 0, 1});
  const Vec3d w = cross(u, e);
  const double l2 = squared_norm(w);
  return l2 > 0.0 ? w * (1.0 / std::sqrt(l2)) : Vec3d{0, 0, 1};
}

/// World frame of a pose: rotation columns, translation and scale. The rotation is exact for
/// a non-unit quaternion too (2/|q|^2 in place of 2), so no square root is needed.
struct Frame {
  Vec3d c0, c1, c2, t;
  double s;
  Vec3d rotate(const Vec3d& v) const { return c0 * v.x + c1 * v.y + c2 * v.z; }
  Vec3d unrotate(const Vec3d& v) const { return {dot(c0, v), dot(c1, v), dot(c2, v)}; }
  /// A point given in unscaled body coordinates.
  Vec3d point(const Vec3d& v) const { return t + rotate(v * s); }
};

Frame frame_of(const Pose& p) {
  double w = p.orientation[0], x = p.orientation[1], y = p.orientation[2], z = p.orientation[3];
  double n = w * w + x * x + y * y + z * z;
  if (!(n > 0.0)) w = 1.0, x = y = z = 0.0, n = 1.0;
  const double k = 2.0 / n;
  Frame f;
  f.c0 = {1.0 - k * (y * y + z * z), k * (x * y + w * z), k * (x * z - w * y)};
  f.c1 = {k * (x * y - w * z), 1.0 - k * (x * x + z * z), k * (y * z + w * x)};
  f.c2 = {k * (x * z + w * y), k * (y * z - w * x), 1.0 - k * (x * x + y * y)};
  f.t = Vec3d::load(p.position);
  f.s = p.scale;
  return f;
}

/// Closest point to x on the segment p0 p1 (p0 if it is degenerate).
Vec3d closest_on_segment(const Vec3d& p0, const Vec3d& p1, const Vec3d& x) {
  const Vec3d u = p1 - p0;
  const double uu = squared_norm(u);
  return uu > 0.0 ? p0 + u * clamp01(dot(x - p0, u) / uu) : p0;
}

struct SegmentPair {
  Vec3d pa, pb;  // closest points on the first and the second segment
};

/// Closest points of segments a0 a1 and b0 b1 (Ericson, Real-Time Collision Detection 5.1.9).
/// Parallel segments take the first segment's start, clamped: deterministic.
SegmentPair closest_segments(const Vec3d& a0, const Vec3d& a1, const Vec3d& b0, const Vec3d& b1) {
  const Vec3d d1 = a1 - a0, d2 = b1 - b0, r = a0 - b0;
  const double a = squared_norm(d1), e = squared_norm(d2), f = dot(d2, r);
  double s = 0.0, t = 0.0;
  if (a <= 0.0 && e <= 0.0) {
  } else if (a <= 0.0) {
    t = clamp01(f / e);
  } else {
    const double c = dot(d1, r);
    if (e <= 0.0) {
      s = clamp01(-c / a);
    } else {
      const double b = dot(d1, d2), denom = a * e - b * b;
      s = denom > 1e-12 * a * e ? clamp01((b * f - c * e) / denom) : 0.0;
      t = (b * s + f) / e;
      if (t < 0.0) {
        t = 0.0;
        s = clamp01(-c / a);
      } else if (t > 1.0) {
        t = 1.0;
        s = clamp01((b - c) / a);
      }
    }
  }
  return {a0 + d1 * s, b0 + d2 * t};
}

// ---- the contact sink -----------------------------------------------------------------------

/// A contact kept in double precision (a triangle surface's, until its manifold is chosen).
struct ContactPointD {
  Vec3d point, normal;
  double penetration;
};

/// Collects up to kMaxManifoldPoints contacts, applying the margin rule in one place; into
/// `exact` instead of `out` when it is set.
struct Sink {
  ContactPoint* out;
  double margin;
  int n = 0;
  ContactPointD* exact = nullptr;

  bool keeps(double penetration) const { return penetration > -margin; }
  void add(const Vec3d& point, const Vec3d& normal, double penetration) {
    if (n >= kMaxManifoldPoints || !keeps(penetration)) return;
    if (exact) {
      exact[n++] = {point, normal, penetration};
      return;
    }
    ContactPoint& c = out[n++];
    c.point[0] = float(point.x), c.point[1] = float(point.y), c.point[2] = float(point.z);
    c.normal[0] = float(normal.x), c.normal[1] = float(normal.y), c.normal[2] = float(normal.z);
    c.penetration = float(penetration);
  }
};

// ---- spheres, capsules, planes --------------------------------------------------------------

struct Segment {
  Vec3d p0, p1;
  double radius;
};
Segment capsule_of(const ShapeView& c, const Frame& f) {
  const Vec3d h = f.c2 * (double(c.half_height) * f.s);
  return {f.t - h, f.t + h, double(c.radius) * f.s};
}

struct Plane {
  Vec3d n;
  double d;  // n.x <= d inside
};
bool plane_of(const ShapeView& p, const Pose& pose, Plane& out) {
  const Vec3d n = Vec3d::load(p.normal);
  const double l = norm(n);
  if (!(l > 0.0)) return false;
  out.n = n * (1.0 / l);
  out.d = double(p.offset) / l * double(pose.scale);
  return true;
}

/// Two spheres; also every pair whose cores reduce to two closest points. `fallback` is the
/// normal when the centres coincide (any direction is then as good as another).
void sphere_sphere(const Vec3d& ca, double ra, const Vec3d& cb, double rb, const Vec3d& fallback, Sink& s) {
  const Vec3d d = cb - ca;
  const double dist2 = squared_norm(d), reach = ra + rb + s.margin;
  if (dist2 >= reach * reach) return;
  const double dist = std::sqrt(dist2);
  const Vec3d n = dist > 0.0 ? d * (1.0 / dist) : fallback;
  s.add(((ca + n * ra) + (cb - n * rb)) * 0.5, n, ra + rb - dist);
}

/// Sphere or capsule end (a) against a plane (b): normal -plane normal.
void sphere_plane(const Vec3d& c, double r, const Plane& pl, Sink& s) {
  const double h = dot(pl.n, c) - pl.d;
  s.add(c - pl.n * ((r + h) * 0.5), -pl.n, r - h);
}

/// Both ends of the core are exact contact features against a plane: each reported if within
/// the margin, so a capsule lying flat gets two points and a steep one gets one.
void capsule_plane(const Segment& c, const Plane& pl, Sink& s) {
  sphere_plane(c.p0, c.radius, pl, s);
  if (squared_norm(c.p1 - c.p0) > 0.0) sphere_plane(c.p1, c.radius, pl, s);
}

void capsule_capsule(const Segment& a, const Segment& b, Sink& s) {
  const Vec3d da = a.p1 - a.p0, db = b.p1 - b.p0;
  const SegmentPair cp = closest_segments(a.p0, a.p1, b.p0, b.p1);
  const Vec3d ab = cross(da, db);
  const double aa = squared_norm(da), bb = squared_norm(db), ab2 = squared_norm(ab);
  // Crossing cores: the shortest way out is perpendicular to both, towards b's centre.
  Vec3d fallback = any_perpendicular(aa > 0.0 ? da : db);
  if (ab2 > 0.0) {
    fallback = ab * (1.0 / std::sqrt(ab2));
    if (dot(fallback, (b.p0 + b.p1) - (a.p0 + a.p1)) < 0.0) fallback = -fallback;
  }
  if (aa > 0.0 && bb > 0.0 && ab2 <= kParallelSin2 * aa * bb) {
    // Near-parallel: contacts at both ends of the overlap of b's projection on a.
    const double la = std::sqrt(aa);
    const Vec3d u = da * (1.0 / la);
    const double t0 = dot(b.p0 - a.p0, u), t1 = dot(b.p1 - a.p0, u);
    const double lo = std::max(0.0, std::min(t0, t1)), hi = std::min(la, std::max(t0, t1));
    if (hi - lo > 1e-6 * la) {
      double deepest = -kInf;
      for (const double t : {lo, hi}) {
        const Vec3d pa = a.p0 + u * t, pb = closest_on_segment(b.p0, b.p1, pa);
        deepest = std::max(deepest, a.radius + b.radius - norm(pb - pa));
        sphere_sphere(pa, a.radius, pb, b.radius, fallback, s);
      }
      // Cores crossing at a small angle between the ends: the true deepest point as well.
      const double pen = a.radius + b.radius - norm(cp.pb - cp.pa);
      if (pen > deepest + 1e-4 * (a.radius + b.radius))
        sphere_sphere(cp.pa, a.radius, cp.pb, b.radius, fallback, s);
      return;
    }
  }
  sphere_sphere(cp.pa, a.radius, cp.pb, b.radius, fallback, s);
}

/// Sphere (a) against a box (b), in the box's frame: clamp for the closest point outside,
/// the nearest face from inside.
void sphere_box(const Vec3d& c, double r, const ShapeView& box, const Frame& f, Sink& s) {
  const Vec3d l = f.unrotate(c - f.t);
  const Vec3d h = Vec3d::load(box.half_extents) * f.s;
  double q[3];
  bool inside = true;
  for (int k = 0; k < 3; ++k) {
    q[k] = std::min(std::max(l[k], -h[k]), h[k]);
    if (q[k] != l[k]) inside = false;
  }
  if (!inside) {
    const Vec3d dl = l - Vec3d::load(q);
    const double dist2 = squared_norm(dl), reach = r + s.margin;
    if (dist2 >= reach * reach) return;
    const double dist = std::sqrt(dist2);  // > 0: the centre is outside
    const Vec3d out = f.rotate(dl) * (1.0 / dist);  // from the box towards the sphere
    const Vec3d qw = f.t + f.rotate(Vec3d::load(q));
    s.add(((c - out * r) + qw) * 0.5, -out, r - dist);
    return;
  }
  int k = 0;
  for (int i = 1; i < 3; ++i)
    if (h[i] - std::fabs(l[i]) < h[k] - std::fabs(l[k])) k = i;
  const Vec3d axis = k == 0 ? f.c0 : (k == 1 ? f.c1 : f.c2);
  const Vec3d out = l[k] < 0.0 ? -axis : axis;
  const double height = std::fabs(l[k]) - h[k];  // <= 0
  s.add(c - out * ((r + height) * 0.5), -out, r - height);
}

// ---- polytopes: boxes and hulls in world space ----------------------------------------------

// A box as a hull: vertex i has the sign pattern of its bits (x: bit 0, y: bit 1, z: bit 2);
// faces -x +x -y +y -z +z, loops counter-clockwise seen from outside.
constexpr int32_t kBoxFaceStart[7] = {0, 4, 8, 12, 16, 20, 24};
constexpr int32_t kBoxFaceVertices[24] = {0, 4, 6, 2, 1, 3, 7, 5, 0, 1, 5, 4,
                                          2, 6, 7, 3, 0, 2, 3, 1, 4, 5, 7, 6};
constexpr int32_t kBoxEdges[24] = {0, 1, 2, 3, 4, 5, 6, 7, 0, 2, 1, 3,
                                   4, 6, 5, 7, 0, 4, 1, 5, 2, 6, 3, 7};
constexpr int16_t kBoxEdgeFaces[12][2] = {{2, 4}, {3, 4}, {2, 5}, {3, 5}, {0, 4}, {1, 4},
                                          {0, 5}, {1, 5}, {0, 2}, {1, 2}, {0, 3}, {1, 3}};

/// A convex polyhedron in world space: transformed vertices and planes, topology borrowed.
struct Polytope {
  int nv = 0, nf = 0, ne = 0;
  const int32_t* face_start = nullptr;
  const int32_t* face_vertices = nullptr;
  const int32_t* edges = nullptr;
  const int16_t (*edge_faces)[2] = nullptr;  // the two faces bordering each edge
  Vec3d centre;                              // mean of the vertices: strictly inside
  double size = 0.0;                         // largest distance of a vertex from the centre
  bool is_box = false;                       // then also its axes and half extents:
  Vec3d axis[3];                             // support in O(1), edges in 3 parallel classes
  double half[3];
  Vec3d v[kMaxHullVertices];
  Vec3d n[kMaxHullFaces];
  double d[kMaxHullFaces];
  int16_t adjacency[kMaxHullEdges][2];  // edge_faces of a hull
};

void make_box(const ShapeView& box, const Frame& f, Polytope& P) {
  const Vec3d h = Vec3d::load(box.half_extents) * f.s;
  P.nv = 8, P.nf = 6, P.ne = 12;
  P.face_start = kBoxFaceStart, P.face_vertices = kBoxFaceVertices, P.edges = kBoxEdges;
  P.edge_faces = kBoxEdgeFaces;
  for (int i = 0; i < 8; ++i)
    P.v[i] = f.t + f.rotate({i & 1 ? h.x : -h.x, i & 2 ? h.y : -h.y, i & 4 ? h.z : -h.z});
  const Vec3d axes[3] = {f.c0, f.c1, f.c2};
  for (int k = 0; k < 3; ++k) {
    const double o = dot(axes[k], f.t);
    P.n[2 * k] = -axes[k], P.d[2 * k] = h[k] - o;
    P.n[2 * k + 1] = axes[k], P.d[2 * k + 1] = h[k] + o;
  }
  P.centre = f.t;
  P.size = norm(h);
  P.is_box = true;
  for (int k = 0; k < 3; ++k) P.axis[k] = axes[k], P.half[k] = h[k];
}

bool hull_fits(const HullView& h) {
  return h.num_vertices >= 1 && h.num_vertices <= kMaxHullVertices && h.num_faces >= 1 &&
         h.num_faces <= kMaxHullFaces && h.num_edges >= 0 && h.num_edges <= kMaxHullEdges &&
         h.vertices && h.planes && h.face_start && h.face_vertices && (h.edges || h.num_edges == 0);
}

/// For each listed edge, the face with its directed loop edge a->b and the one with b->a:
/// directed loop edges bucketed by their first vertex (counting sort), then looked up.
/// False if a loop or edge index is out of range or an edge lacks a face on either side.
bool edge_faces_of(const HullView& h, int16_t (*adj)[2]) {
  const int nv = h.num_vertices, nf = h.num_faces;
  if (h.face_start[0] != 0) return false;
  for (int f = 0; f < nf; ++f)
    if (h.face_start[f + 1] - h.face_start[f] < 3) return false;
  const int total = h.face_start[nf];
  if (total > kMaxHullLoopLength) return false;
  int16_t first[kMaxHullVertices + 1], fill[kMaxHullVertices];
  int16_t to[kMaxHullLoopLength], face_of[kMaxHullLoopLength];
  std::fill(first, first + nv + 1, int16_t(0));
  for (int k = 0; k < total; ++k) {
    const int from = h.face_vertices[k];
    if (from < 0 || from >= nv) return false;
    ++first[from + 1];
  }
  for (int i = 1; i <= nv; ++i) first[i] = int16_t(first[i] + first[i - 1]);
  std::copy(first, first + nv, fill);
  for (int f = 0; f < nf; ++f) {
    const int b = h.face_start[f], e = h.face_start[f + 1];
    for (int k = b; k < e; ++k) {
      const int slot = fill[h.face_vertices[k]]++;
      to[slot] = int16_t(h.face_vertices[k + 1 < e ? k + 1 : b]);
      face_of[slot] = int16_t(f);
    }
  }
  auto find = [&](int a, int b) {
    for (int k = first[a]; k < first[a + 1]; ++k)
      if (to[k] == b) return int(face_of[k]);
    return -1;
  };
  for (int e = 0; e < h.num_edges; ++e) {
    const int a = h.edges[2 * e], b = h.edges[2 * e + 1];
    if (a < 0 || a >= nv || b < 0 || b >= nv) return false;
    const int f1 = find(a, b), f2 = find(b, a);
    if (f1 < 0 || f2 < 0) return false;
    adj[e][0] = int16_t(f1), adj[e][1] = int16_t(f2);
  }
  return true;
}

/// A hull in world space; with_edges also finds the faces of each edge (needed by the edge
/// axes). False if the hull does not fit the bounds or its edges are inconsistent.
bool make_hull(const ShapeView& shape, const Frame& f, bool with_edges, Polytope& P) {
  const HullView& h = shape.hull;
  if (!hull_fits(h)) return false;
  P.nv = h.num_vertices, P.nf = h.num_faces, P.ne = h.num_edges;
  P.face_start = h.face_start, P.face_vertices = h.face_vertices, P.edges = h.edges;
  Vec3d sum{0, 0, 0};
  for (int i = 0; i < P.nv; ++i) {
    P.v[i] = f.point(Vec3d::load(h.vertices + 3 * i));
    sum = sum + P.v[i];
  }
  P.centre = sum * (1.0 / P.nv);
  double r2 = 0.0;
  for (int i = 0; i < P.nv; ++i) r2 = std::max(r2, squared_norm(P.v[i] - P.centre));
  P.size = std::sqrt(r2);
  for (int i = 0; i < P.nf; ++i) {
    P.n[i] = f.rotate(Vec3d::load(h.planes + 4 * i));
    P.d[i] = double(h.planes[4 * i + 3]) * f.s + dot(P.n[i], f.t);
  }
  if (!with_edges) return true;
  if (!edge_faces_of(h, P.adjacency)) return false;
  P.edge_faces = P.adjacency;
  return true;
}

/// Picks at most four of n points spanning the largest area: the deepest, the farthest from
/// it, the largest triangle, then the point adding the most area. The penalty forces need the
/// support polygon, not every point. Ties go to the lower index; the indices come out sorted
/// (clipped polygons keep their winding). eps2: squared length below which points coincide.
int reduce_spread(const Vec3d* p, const double* depth, int n, const Vec3d& normal, double eps2, int keep[4]);

int reduce_manifold(const Vec3d* p, const double* depth, int n, const Vec3d& normal, double eps2, int keep[4]) {
  if (n <= 4) {
    for (int i = 0; i < n; ++i) keep[i] = i;
    return n;
  }
  return reduce_spread(p, depth, n, normal, eps2, keep);
}

/// The same choice for any n: a point adding no area (a repeat, or one between two others on a
/// line) is dropped even when there are four or fewer.
int reduce_spread(const Vec3d* p, const double* depth, int n, const Vec3d& normal, double eps2, int keep[4]) {
  if (n <= 0) return 0;
  int i0 = 0;
  for (int i = 1; i < n; ++i)
    if (depth[i] > depth[i0]) i0 = i;
  int i1 = -1;
  double best = eps2;
  for (int i = 0; i < n; ++i) {
    const double d2 = squared_norm(p[i] - p[i0]);
    if (d2 > best) best = d2, i1 = i;
  }
  if (i1 < 0) return keep[0] = i0, 1;
  const Vec3d e01 = p[i1] - p[i0];
  int i2 = -1;
  double area = 0.0, best_area = eps2 * 1e-3;  // |cross| is a length squared
  for (int i = 0; i < n; ++i) {
    const double a = dot(cross(e01, p[i] - p[i0]), normal);
    if (std::fabs(a) > best_area) best_area = std::fabs(a), area = a, i2 = i;
  }
  int m = 2;
  keep[0] = i0, keep[1] = i1;
  if (i2 >= 0) {
    keep[m++] = i2;
    // The point farthest outside the triangle's edges adds the most area.
    const double sgn = area > 0.0 ? 1.0 : -1.0;
    const int tri[3] = {i0, i1, i2};
    int i3 = -1;
    double most = eps2 * 1e-3;
    for (int i = 0; i < n; ++i) {
      if (i == i0 || i == i1 || i == i2) continue;
      double outside = 0.0;
      for (int k = 0; k < 3; ++k) {
        const Vec3d& a = p[tri[k]];
        const Vec3d& b = p[tri[(k + 1) % 3]];
        outside = std::max(outside, -sgn * dot(cross(b - a, p[i] - a), normal));
      }
      if (outside > most) most = outside, i3 = i;
    }
    if (i3 >= 0) keep[m++] = i3;
  }
  std::sort(keep, keep + m);
  return m;
}

// ---- a point or a segment against a polytope ------------------------------------------------

/// Squared distance from an outside point x to the polytope, and the closest point q: the
/// closest point lies on a face whose plane x is above, so only those faces are searched.
double closest_on_polytope(const Polytope& P, const Vec3d& x, Vec3d& q) {
  double best = kInf;
  for (int f = 0; f < P.nf; ++f) {
    const Vec3d& n = P.n[f];
    const double h = dot(n, x) - P.d[f];
    if (h <= 0.0 || h * h >= best) continue;
    const int b = P.face_start[f], e = P.face_start[f + 1];
    const Vec3d y = x - n * h;  // projection on the face plane
    bool inside = true;
    for (int k = b; k < e && inside; ++k) {
      const Vec3d& v0 = P.v[P.face_vertices[k]];
      const Vec3d& v1 = P.v[P.face_vertices[k + 1 < e ? k + 1 : b]];
      if (dot(cross(v1 - v0, n), y - v0) > 0.0) inside = false;
    }
    if (inside) {
      best = h * h, q = y;
      continue;
    }
    for (int k = b; k < e; ++k) {
      const Vec3d c = closest_on_segment(P.v[P.face_vertices[k]], P.v[P.face_vertices[k + 1 < e ? k + 1 : b]], x);
      const double d2 = squared_norm(x - c);
      if (d2 < best) best = d2, q = c;
    }
  }
  return best;
}

/// Sphere (a) against a polytope (b).
void sphere_polytope(const Vec3d& c, double r, const Polytope& P, Sink& s) {
  int face = 0;
  double height = -kInf;
  for (int f = 0; f < P.nf; ++f) {
    const double h = dot(P.n[f], c) - P.d[f];
    if (h > height) height = h, face = f;
  }
  if (height >= r + s.margin) return;  // a face plane separates them
  if (height <= 0.0) {                 // centre inside: out through the nearest face plane
    const Vec3d& n = P.n[face];
    s.add(c - n * ((r + height) * 0.5), -n, r - height);
    return;
  }
  Vec3d q;
  const double dist = std::sqrt(closest_on_polytope(P, c, q));  // >= height > 0
  if (!s.keeps(r - dist)) return;
  const Vec3d out = (c - q) * (1.0 / dist);
  s.add(((c - out * r) + q) * 0.5, -out, r - dist);
}

/// Clips the core segment to the prism over face f of P and reports both clipped ends against
/// the face plane (exact there: the face plane supports P). Returns whether a point was added.
bool segment_on_face(const Segment& c, const Polytope& P, int f, Sink& s) {
  const Vec3d& n = P.n[f];
  const Vec3d u = c.p1 - c.p0;
  double t0 = 0.0, t1 = 1.0;
  const int b = P.face_start[f], e = P.face_start[f + 1];
  for (int k = b; k < e; ++k) {
    const Vec3d& v0 = P.v[P.face_vertices[k]];
    const Vec3d side = cross(P.v[P.face_vertices[k + 1 < e ? k + 1 : b]] - v0, n);  // outward
    const double f0 = dot(side, c.p0 - v0), fu = dot(side, u);  // side distance f0 + t fu
    if (fu == 0.0) {
      if (f0 > 0.0) return false;
      continue;
    }
    const double t = -f0 / fu;
    if (fu > 0.0) t1 = std::min(t1, t);
    else t0 = std::max(t0, t);
    if (t0 > t1) return false;
  }
  const int before = s.n;
  for (int k = 0; k < 2; ++k) {
    if (k == 1 && t1 - t0 <= 1e-9) break;
    const Vec3d x = c.p0 + u * (k ? t1 : t0);
    const double h = dot(n, x) - P.d[f];
    s.add(x - n * ((h + c.radius) * 0.5), -n, c.radius - h);
  }
  return s.n > before;
}

struct FaceQuery {
  double sep = -kInf;  // largest separation of a face plane from the other shape
  int face = -1;
};
struct EdgeQuery {
  double sep = -kInf;
  int ea = -1, eb = -1;
  Vec3d axis{0, 0, 0};  // unit, pointing out of the first polytope
};

/// Capsule (a) against a polytope (b). The core is tested against the separating axes (face
/// normals, and edge x core where the edge's normal arc crosses the core's great circle). If
/// the core is outside, exact closest points give the contact; if it touches or crosses, the
/// least-penetration axis does. A core lying along a face gives the two clipped ends.
void capsule_polytope(const Segment& c, const Polytope& P, Sink& s) {
  const Vec3d u = c.p1 - c.p0;
  if (squared_norm(u) == 0.0) return sphere_polytope(c.p0, c.radius, P, s);
  const double reach = c.radius + s.margin;
  FaceQuery fq;
  for (int f = 0; f < P.nf; ++f) {
    const double sep = std::min(dot(P.n[f], c.p0), dot(P.n[f], c.p1)) - P.d[f];
    if (sep > fq.sep) fq.sep = sep, fq.face = f;
  }
  if (fq.sep >= reach || fq.face < 0) return;  // (no face: NaN in the input)
  EdgeQuery eq;
  for (int e = 0; e < P.ne; ++e) {
    const double a0 = dot(P.n[P.edge_faces[e][0]], u), a1 = dot(P.n[P.edge_faces[e][1]], u);
    if (!(a0 * a1 < 0.0)) continue;
    const Vec3d& q0 = P.v[P.edges[2 * e]];
    const Vec3d ev = P.v[P.edges[2 * e + 1]] - q0;
    Vec3d axis = cross(ev, u);
    const double l2 = squared_norm(axis);
    if (l2 <= kEdgeParallelSin2 * squared_norm(ev) * squared_norm(u)) continue;
    axis = axis * (1.0 / std::sqrt(l2));
    if (dot(axis, q0 - P.centre) < 0.0) axis = -axis;
    const double sep = std::min(dot(axis, c.p0), dot(axis, c.p1)) - dot(axis, q0);
    if (sep > eq.sep) eq.sep = sep, eq.ea = e, eq.axis = axis;
  }
  if (eq.sep >= reach) return;

  if (std::max(fq.sep, eq.sep) > 0.0) {
    // Core outside: closest points are at an end of the core or between it and an edge.
    Vec3d pc = c.p0, qc;
    double best = closest_on_polytope(P, c.p0, qc);
    Vec3d q1;
    const double d1 = closest_on_polytope(P, c.p1, q1);
    if (d1 < best) best = d1, pc = c.p1, qc = q1;
    for (int e = 0; e < P.ne; ++e) {
      const SegmentPair sp = closest_segments(c.p0, c.p1, P.v[P.edges[2 * e]], P.v[P.edges[2 * e + 1]]);
      const double d2 = squared_norm(sp.pb - sp.pa);
      if (d2 < best) best = d2, pc = sp.pa, qc = sp.pb;
    }
    if (best >= reach * reach) return;
    const double dist = std::sqrt(best);  // >= the positive separation
    const Vec3d out = (pc - qc) * (1.0 / dist);
    int face = 0;
    for (int f = 1; f < P.nf; ++f)
      if (dot(P.n[f], out) > dot(P.n[face], out)) face = f;
    if (dot(P.n[face], out) >= kParallelCos && segment_on_face(c, P, face, s)) return;
    s.add(((pc - out * c.radius) + qc) * 0.5, -out, c.radius - dist);
    return;
  }
  // Core touching or crossing: the least-penetration axis, faces preferred.
  const double tol = kBiasAbs * std::min(P.size, c.radius + 0.5 * norm(u));
  if (eq.ea >= 0 && eq.sep > fq.sep + kEdgeRel * std::fabs(fq.sep) + tol) {
    const SegmentPair sp = closest_segments(c.p0, c.p1, P.v[P.edges[2 * eq.ea]], P.v[P.edges[2 * eq.ea + 1]]);
    s.add(((sp.pa - eq.axis * c.radius) + sp.pb) * 0.5, -eq.axis, c.radius - eq.sep);
    return;
  }
  if (segment_on_face(c, P, fq.face, s)) return;
  const Vec3d& n = P.n[fq.face];
  const Vec3d x = dot(n, c.p0) <= dot(n, c.p1) ? c.p0 : c.p1;  // the deeper end
  const double h = dot(n, x) - P.d[fq.face];
  s.add(x - n * ((h + c.radius) * 0.5), -n, c.radius - h);
}

// ---- a polytope against a plane -------------------------------------------------------------

/// The vertices within the margin of the plane, reduced to the four spanning the largest
/// area: a box lying flat gives its four bottom corners, a hull on a face that face's corners.
void polytope_plane(const Polytope& P, const Plane& pl, Sink& s) {
  Vec3d pts[kMaxHullVertices];
  double depth[kMaxHullVertices];
  int m = 0;
  for (int i = 0; i < P.nv; ++i) {
    const double pen = pl.d - dot(pl.n, P.v[i]);
    if (s.keeps(pen)) pts[m] = P.v[i], depth[m] = pen, ++m;
  }
  int keep[4];
  const double eps = 1e-6 * P.size;
  const int k = reduce_manifold(pts, depth, m, pl.n, eps * eps, keep);
  for (int i = 0; i < k; ++i) s.add(pts[keep[i]] + pl.n * (depth[keep[i]] * 0.5), -pl.n, depth[keep[i]]);
}

// ---- polytope against polytope --------------------------------------------------------------

/// min over P of n.x: a box's from its axes, a hull's from its vertices (two running minima,
/// so the comparisons do not wait on each other).
double lowest_along(const Polytope& P, const Vec3d& n) {
  if (P.is_box)
    return dot(n, P.centre) - (P.half[0] * std::fabs(dot(n, P.axis[0])) + P.half[1] * std::fabs(dot(n, P.axis[1])) +
                               P.half[2] * std::fabs(dot(n, P.axis[2])));
  double m0 = dot(n, P.v[0]), m1 = m0;
  int j = 1;
  for (; j + 1 < P.nv; j += 2) m0 = std::min(m0, dot(n, P.v[j])), m1 = std::min(m1, dot(n, P.v[j + 1]));
  if (j < P.nv) m0 = std::min(m0, dot(n, P.v[j]));
  return std::min(m0, m1);
}

/// Largest separation of a face plane of A from B (B's deepest point below it). Stops early
/// once a face separates by more than cutoff.
FaceQuery query_faces(const Polytope& A, const Polytope& B, double cutoff) {
  FaceQuery q;
  for (int i = 0; i < A.nf; ++i) {
    const double sep = lowest_along(B, A.n[i]) - A.d[i];
    if (sep > q.sep) {
      q.sep = sep, q.face = i;
      if (sep > cutoff) break;
    }
  }
  return q;
}

/// query_edges for two boxes: their 12 edges are 3 parallel classes each, so there are 9
/// pairs of edge directions, each crossing on the Gauss map in one pair of edges per sign of
/// the axis, the one facing b being the better. Support functions give the separation and the
/// supporting edges directly (the same axes and edges as the general query, in O(9)).
EdgeQuery query_edges_boxes(const Polytope& A, const Polytope& B, double cutoff) {
  // Edge index of the class along axis k (kBoxEdges) for the vertex bits of the other two.
  constexpr int kClassStart[3] = {0, 4, 8};
  const Vec3d t = B.centre - A.centre;
  EdgeQuery q;
  for (int ka = 0; ka < 3; ++ka)
    for (int kb = 0; kb < 3; ++kb) {
      Vec3d axis = cross(A.axis[ka], B.axis[kb]);  // not normalised until the end: the square
      const double l2 = squared_norm(axis);        // root runs beside the dot products
      if (l2 <= kEdgeParallelSin2) continue;       // unit axes
      const double inv = 1.0 / std::sqrt(l2);
      const double at = dot(axis, t);
      if (at < 0.0) axis = -axis;
      double ra = 0.0, rb = 0.0;
      int ea = kClassStart[ka], eb = kClassStart[kb], bit_a = 1, bit_b = 1;
      for (int m = 0; m < 3; ++m) {
        const double ua = dot(axis, A.axis[m]), ub = dot(axis, B.axis[m]);
        ra += A.half[m] * std::fabs(ua), rb += B.half[m] * std::fabs(ub);
        // A's support edge is on the +axis side, B's on the -axis side.
        if (m != ka) ea += ua > 0.0 ? bit_a : 0, bit_a *= 2;
        if (m != kb) eb += ub < 0.0 ? bit_b : 0, bit_b *= 2;
      }
      const double sep = (std::fabs(at) - ra - rb) * inv;
      if (sep > q.sep) {
        q.sep = sep, q.ea = ea, q.eb = eb, q.axis = axis * inv;
        if (sep > cutoff) return q;
      }
    }
  return q;
}

/// The largest w.r over unit w on the shorter great arc from n0 to n1 (an edge's normals).
double arc_max(const Vec3d& n0, const Vec3d& n1, const Vec3d& r) {
  double best = std::max(dot(n0, r), dot(n1, r));
  const Vec3d e = cross(n0, n1);
  const double ee = squared_norm(e);
  if (ee > 0.0) {
    const Vec3d rp = r - e * (dot(e, r) / ee);  // r in the arc's plane: the best direction if inside
    if (dot(cross(n0, rp), e) > 0.0 && dot(cross(rp, n1), e) > 0.0) best = std::max(best, norm(rp));
  }
  return best;
}

/// Largest separation along the cross products of A's and B's edges that form faces of the
/// Minkowski difference A - B (Gregorius, "The Separating Axis Test between Convex Polyhedra",
/// GDC 2013): edges whose arcs on the Gauss map cross, a-b (A's face normals) and c-d (B's,
/// negated). Other pairs are not candidate axes. Pairs that cannot reach `floor` are skipped
/// (the caller has no use for them): along any u in A's edge's arc the separation is at most
/// u.(centre of B - edge point), since B's centre is inside B, and likewise for B's edges.
/// Stops early once an axis separates by more than cutoff.
EdgeQuery query_edges(const Polytope& A, const Polytope& B, double cutoff, double floor) {
  if (A.is_box && B.is_box) return query_edges_boxes(A, B, cutoff);
  int16_t active_b[kMaxHullEdges];
  int nb = 0;
  for (int j = 0; j < B.ne; ++j) {
    active_b[nb] = int16_t(j);
    nb += arc_max(B.n[B.edge_faces[j][0]], B.n[B.edge_faces[j][1]], A.centre - B.v[B.edges[2 * j]]) >= floor;
  }
  // Each edge's arc plane, n1 x n0 of its faces (b x a for A; for B, d x c with c, d negated
  // is the same expression).
  Vec3d arc_b[kMaxHullEdges];
  for (int k = 0; k < nb; ++k) {
    const int j = active_b[k];
    arc_b[j] = cross(B.n[B.edge_faces[j][1]], B.n[B.edge_faces[j][0]]);
  }
  double side[kMaxHullFaces];  // B's normals against the plane of A's current arc
  int16_t crossing[kMaxHullEdges];
  // The best so far as s / sqrt(l2) (unnormalised axis): compared without square roots.
  double best_s = -1.0, best_l2 = 0.0;
  int best_i = -1, best_j = -1;
  Vec3d best_axis{0, 0, 0};
  for (int i = 0; i < A.ne; ++i) {
    const Vec3d& a = A.n[A.edge_faces[i][0]];
    const Vec3d& b = A.n[A.edge_faces[i][1]];
    const Vec3d& pa = A.v[A.edges[2 * i]];
    if (arc_max(a, b, B.centre - pa) < floor) continue;
    const Vec3d b_x_a = cross(b, a);
    for (int f = 0; f < B.nf; ++f) side[f] = dot(B.n[f], b_x_a);
    // c and d (B's normals negated) on opposite sides of a-b's plane: gathered without
    // branches, as the outcome is a coin toss the branch predictor would keep losing.
    int m = 0;
    for (int k = 0; k < nb; ++k) {
      const int j = active_b[k];
      crossing[m] = int16_t(j);
      m += side[B.edge_faces[j][0]] * side[B.edge_faces[j][1]] < 0.0;
    }
    const Vec3d ea = A.v[A.edges[2 * i + 1]] - pa;
    const double la2 = squared_norm(ea);
    for (int k = 0; k < m; ++k) {
      const int j = crossing[k];
      // ...a and b on opposite sides of c-d's, and the crossing on the near hemisphere.
      const double cba = -side[B.edge_faces[j][0]];
      const double adc = dot(a, arc_b[j]), bdc = dot(b, arc_b[j]);
      if (!(adc * bdc < 0.0 && cba * bdc > 0.0)) continue;
      const Vec3d& pb = B.v[B.edges[2 * j]];
      const Vec3d eb = B.v[B.edges[2 * j + 1]] - pb;
      const Vec3d axis = cross(ea, eb);
      const double l2 = squared_norm(axis);
      if (l2 <= kEdgeParallelSin2 * la2 * squared_norm(eb)) continue;
      // Separation along the axis turned out of A: s / sqrt(l2).
      double s = dot(axis, pb - pa);
      if (dot(axis, pa - A.centre) < 0.0) s = -s;
      const bool better = best_i < 0 || (s >= 0.0 ? best_s < 0.0 || s * s * best_l2 > best_s * best_s * l2
                                                  : best_s < 0.0 && s * s * best_l2 < best_s * best_s * l2);
      if (!better) continue;
      best_s = s, best_l2 = l2, best_i = i, best_j = j, best_axis = axis;
      if (s > 0.0 && s * s > cutoff * cutoff * l2) break;
    }
    if (best_i >= 0 && best_s > 0.0 && best_s * best_s > cutoff * cutoff * best_l2) break;
  }
  EdgeQuery q;
  if (best_i < 0) return q;
  const double inv = 1.0 / std::sqrt(best_l2);
  const Vec3d& pa = A.v[A.edges[2 * best_i]];
  q.ea = best_i, q.eb = best_j, q.sep = best_s * inv;
  q.axis = best_axis * (dot(best_axis, pa - A.centre) < 0.0 ? -inv : inv);
  return q;
}

/// Clips the polygon in[0..n) to the half-space side.x <= offset (Sutherland-Hodgman).
int clip_polygon(const Vec3d* in, int n, const Vec3d& side, double offset, Vec3d* out) {
  int m = 0;
  Vec3d prev = in[n - 1];
  double dp = dot(side, prev) - offset;
  for (int i = 0; i < n; ++i) {
    const Vec3d& cur = in[i];
    const double dc = dot(side, cur) - offset;
    if (dp <= 0.0) {
      out[m++] = dc <= 0.0 ? cur : prev + (cur - prev) * (dp / (dp - dc));
    } else if (dc <= 0.0) {
      out[m++] = prev + (cur - prev) * (dp / (dp - dc));
      out[m++] = cur;
    }
    prev = cur, dp = dc;
  }
  return m;
}

constexpr int kClipCapacity = 2 * kMaxHullVertices;  // incident loop + one per reference side

/// A face contact before it is reported: points on I's surface and their depths under the
/// reference plane (normal n, out of R).
struct FaceManifold {
  Vec3d n;
  int count = 0;
  Vec3d point[kMaxManifoldPoints];
  double depth[kMaxManifoldPoints];
  double deepest = -kInf;
};

/// Face contact: the incident face of I (most anti-parallel to the reference normal, among
/// those holding I's deepest vertex) clipped to the side planes of reference face rf of R;
/// the points below the reference plane (or within the margin above it), reduced to four.
/// False if no point qualifies.
bool face_contact(const Polytope& R, int rf, const Polytope& I, double margin, FaceManifold& fm) {
  const Vec3d n = R.n[rf];
  const double d = R.d[rf];
  fm.n = n;
  // (The most anti-parallel face overall can miss the deepest vertex, and with it the contact.)
  int deepest = 0;
  for (int i = 1; i < I.nv; ++i)
    if (dot(n, I.v[i]) < dot(n, I.v[deepest])) deepest = i;
  int inc = -1;
  for (int f = 0; f < I.nf; ++f)
    for (int k = I.face_start[f]; k < I.face_start[f + 1]; ++k)
      if (I.face_vertices[k] == deepest && (inc < 0 || dot(I.n[f], n) < dot(I.n[inc], n))) inc = f;
  const int b = R.face_start[rf], e = R.face_start[rf + 1];
  // (A loop longer than the vertex count, or a vertex on no face: not a hull.)
  if (inc < 0 || I.face_start[inc + 1] - I.face_start[inc] > kMaxHullVertices || e - b > kMaxHullVertices) return false;
  Vec3d buf0[kClipCapacity], buf1[kClipCapacity];
  Vec3d* poly = buf0;
  Vec3d* next = buf1;
  int m = 0;
  for (int k = I.face_start[inc]; k < I.face_start[inc + 1]; ++k) poly[m++] = I.v[I.face_vertices[k]];
  for (int k = b; k < e && m > 0; ++k) {
    const Vec3d& v0 = R.v[R.face_vertices[k]];
    const Vec3d side = cross(R.v[R.face_vertices[k + 1 < e ? k + 1 : b]] - v0, n);  // outward
    m = clip_polygon(poly, m, side, dot(side, v0), next);
    std::swap(poly, next);
  }
  // Keep the points within the margin of the reference plane, dropping the repeats that
  // clipping makes where a vertex lies on a side plane.
  const double eps = 1e-6 * (R.size + I.size), eps2 = eps * eps;
  double depth[kClipCapacity];
  int k = 0;
  for (int i = 0; i < m; ++i) {
    const double pen = d - dot(n, poly[i]);
    if (!(pen > -margin) || (k > 0 && squared_norm(poly[i] - poly[k - 1]) <= eps2)) continue;
    poly[k] = poly[i], depth[k] = pen, ++k;
  }
  if (k > 1 && squared_norm(poly[k - 1] - poly[0]) <= eps2) --k;
  int keep[4];
  fm.count = reduce_manifold(poly, depth, k, n, eps2, keep);
  for (int i = 0; i < fm.count; ++i) {
    fm.point[i] = poly[keep[i]], fm.depth[i] = depth[keep[i]];
    fm.deepest = std::max(fm.deepest, fm.depth[i]);
  }
  return fm.count > 0;
}

/// Edge contact: the closest points of the two edges, one point.
void edge_contact(const Polytope& A, const Polytope& B, const EdgeQuery& ee, Sink& s) {
  const SegmentPair sp = closest_segments(A.v[A.edges[2 * ee.ea]], A.v[A.edges[2 * ee.ea + 1]],
                                          B.v[B.edges[2 * ee.eb]], B.v[B.edges[2 * ee.eb + 1]]);
  s.add((sp.pa + sp.pb) * 0.5, ee.axis, -ee.sep);
}

/// Polytope (a) against polytope (b): separating axis test, then a face or an edge contact.
void polytope_polytope(const Polytope& A, const Polytope& B, Sink& s) {
  const FaceQuery fa = query_faces(A, B, s.margin);
  if (fa.sep > s.margin) return;
  const FaceQuery fb = query_faces(B, A, s.margin);
  if (fb.sep > s.margin || fa.face < 0 || fb.face < 0) return;  // (no face: NaN in the input)
  const double tol = kBiasAbs * std::min(A.size, B.size);
  // Edge axes below this can neither win over the faces nor stand in for them (below).
  const double best_face = std::max(fa.sep, fb.sep);
  const EdgeQuery ee = query_edges(A, B, s.margin, best_face - kEdgeRel * std::fabs(best_face) - 3 * tol);
  if (ee.sep > s.margin) return;
  const bool ref_b = fb.sep > fa.sep + kFaceRel * std::fabs(fa.sep) + tol;
  const double face_sep = ref_b ? fb.sep : fa.sep;
  if (ee.ea >= 0 && ee.sep > face_sep + kEdgeRel * std::fabs(face_sep) + tol) return edge_contact(A, B, ee, s);
  const Polytope& R = ref_b ? B : A;
  const Polytope& I = ref_b ? A : B;
  const int rf = ref_b ? fb.face : fa.face;
  FaceManifold fm;
  const bool found = face_contact(R, rf, I, s.margin, fm);
  // The face axis won only by its bias over an edge axis, and clipping to the reference face
  // lost the depth that edge pair has (the overlap reaches past the face's sides): the
  // contact is at the edges.
  if (ee.ea >= 0 && ee.sep >= face_sep - tol && (!found || fm.deepest < -ee.sep - tol))
    return edge_contact(A, B, ee, s);
  const Vec3d normal = ref_b ? -fm.n : fm.n;
  if (found) {
    for (int i = 0; i < fm.count; ++i) s.add(fm.point[i] + fm.n * (fm.depth[i] * 0.5), normal, fm.depth[i]);
    return;
  }
  // Nothing over the reference face and no edge axis close to it: I's deepest vertex.
  int deepest = 0;
  for (int i = 1; i < I.nv; ++i)
    if (dot(fm.n, I.v[i]) < dot(fm.n, I.v[deepest])) deepest = i;
  const double pen = R.d[rf] - dot(fm.n, I.v[deepest]);
  s.add(I.v[deepest] + fm.n * (pen * 0.5), normal, pen);
}

// ---- several calls' contacts as one manifold -------------------------------------------------

/// Contacts gathered from several calls (a surface's triangles, a compound's parts), in double
/// precision, and reduced to one manifold of at most kMaxManifoldPoints: the deepest point's
/// normal decides the winding.
struct Gather {
  static constexpr int kCapacity = 64;
  Vec3d pts[kCapacity + kMaxManifoldPoints], nrm[kCapacity + kMaxManifoldPoints];
  double depth[kCapacity + kMaxManifoldPoints];
  int count = 0;
  double size = 0.0;  // a length of the shapes, for the tolerances (0: the points' own spread)
  // Of points as deep to a thousandth of `size`, the first kept is the one farthest from their
  // middle, and points that add no area go even when four or fewer are left: triangles clip a
  // flat contact at their edges, and the support polygon's corners, not a clipped point inside
  // it or a repeat, are what a plane would give.
  bool corners = false;

  void add(const Vec3d& p, const Vec3d& n, double d) {
    if (count == kCapacity + kMaxManifoldPoints) return;  // (reduce() keeps room: not reached)
    pts[count] = p, nrm[count] = n, depth[count] = d, ++count;
  }
  /// Makes room for n more, reducing what is there if need be.
  void room_for(int n) {
    if (count + n > kCapacity) reduce();
  }
  void reduce() {
    if (count <= (corners ? 1 : kMaxManifoldPoints)) return;
    int deepest = 0;
    for (int i = 1; i < count; ++i)
      if (depth[i] > depth[deepest]) deepest = i;
    double length = size;
    for (int i = 1; length <= 0.0 && i < count; ++i) length = std::max(length, norm(pts[i] - pts[0]));
    const double eps = 1e-6 * length;
    int keep[4], k = 0;
    if (corners) {
      const double level = depth[deepest] - 1e-3 * length;
      Vec3d mid{0, 0, 0};
      for (int i = 0; i < count; ++i) mid = mid + pts[i] * (1.0 / count);
      double first[kCapacity + kMaxManifoldPoints];
      for (int i = 0; i < count; ++i) first[i] = depth[i] >= level ? 1.0 + squared_norm(pts[i] - mid) : 0.0;
      k = reduce_spread(pts, first, count, nrm[deepest], eps * eps, keep);
    } else {
      k = reduce_manifold(pts, depth, count, nrm[deepest], eps * eps, keep);
    }
    for (int i = 0; i < k; ++i) pts[i] = pts[keep[i]], nrm[i] = nrm[keep[i]], depth[i] = depth[keep[i]];
    count = k;
  }
};

// ---- triangle surfaces: meshes and height fields --------------------------------------------

// A triangle collides as a prism: its face on top, extruded behind it by about twice the other
// shape's size, so the general routines above find the contact and a shape sunk a little into
// the surface is still pushed out of its front. Vertices 0-2 are the triangle, 3-5 the same
// moved behind it; faces: the front, the back, then the side under edge k (vertex k to k + 1).
constexpr int32_t kPrismFaceStart[6] = {0, 3, 6, 10, 14, 18};
constexpr int32_t kPrismFaceVertices[18] = {0, 1, 2, 3, 5, 4, 0, 3, 4, 1, 1, 4, 5, 2, 2, 5, 3, 0};
constexpr int32_t kPrismEdges[18] = {0, 1, 1, 2, 2, 0, 3, 4, 4, 5, 5, 3, 0, 3, 1, 4, 2, 5};
constexpr int16_t kPrismEdgeFaces[9][2] = {{0, 2}, {0, 3}, {0, 4}, {1, 2}, {1, 3}, {1, 4}, {2, 4}, {3, 2}, {4, 3}};
// A contact normal this close to the triangle's is its face normal.
constexpr double kFaceNormalCos = 0.9999;

struct SurfaceTriangle {
  Vec3d v[3], n;
  uint8_t active = 0;  // bit k: edge k (vertex k to k + 1) is active
};

SurfaceTriangle triangle_of(const MeshView& m, const Frame& f, int t) {
  SurfaceTriangle tr;
  const int32_t* ix = m.triangles + 3 * t;
  for (int c = 0; c < 3; ++c) tr.v[c] = f.point(Vec3d::load(m.vertices + 3 * ix[c]));
  tr.n = f.rotate(Vec3d::load(m.normals + 3 * t));
  tr.active = m.edge_flags[t];
  return tr;
}

void make_prism(const SurfaceTriangle& t, double depth, Polytope& P) {
  P.nv = 6, P.nf = 5, P.ne = 9;
  P.face_start = kPrismFaceStart, P.face_vertices = kPrismFaceVertices, P.edges = kPrismEdges;
  P.edge_faces = kPrismEdgeFaces;
  P.is_box = false;
  const double d0 = dot(t.n, t.v[0]);
  P.centre = {0, 0, 0};
  for (int i = 0; i < 3; ++i) {
    P.v[i] = t.v[i], P.v[i + 3] = t.v[i] - t.n * depth;
    P.centre = P.centre + (P.v[i] + P.v[i + 3]) * (1.0 / 6.0);
  }
  P.n[0] = t.n, P.d[0] = d0;
  P.n[1] = -t.n, P.d[1] = depth - d0;
  for (int k = 0; k < 3; ++k) {
    const Vec3d side = cross(t.v[(k + 1) % 3] - t.v[k], t.n);
    P.n[2 + k] = side * (1.0 / norm(side));  // the dictionary keeps only triangles with an area
    P.d[2 + k] = dot(P.n[2 + k], t.v[k]);
  }
  P.size = 0.0;
  for (int i = 0; i < 6; ++i) P.size = std::max(P.size, norm(P.v[i] - P.centre));
}

/// The other shape of a surface pair, in world space.
struct SurfaceVisitor {
  ShapeType type = ShapeType::sphere;  // sphere, capsule, or a polytope (box, hull)
  Vec3d centre;
  double radius = 0.0, size = 0.0;
  Segment core;                  // capsule
  const Polytope* P = nullptr;   // box, hull
  Vec3d lo, hi;                  // its box
};

void visitor_vs_prism(const SurfaceVisitor& a, const Polytope& T, Sink& s) {
  if (a.type == ShapeType::sphere) return sphere_polytope(a.centre, a.radius, T, s);
  if (a.type == ShapeType::capsule) return capsule_polytope(a.core, T, s);
  polytope_polytope(*a.P, T, s);
}

/// The contact against the triangle's face alone, clipped to the triangle: what a shape on an
/// inactive edge gets, as it would from the one plane the neighbouring triangles share.
void visitor_on_face(const SurfaceVisitor& a, const Polytope& T, Sink& s) {
  const Vec3d& n = T.n[0];
  if (a.type == ShapeType::sphere) {
    const double h = dot(n, a.centre) - T.d[0];
    const Vec3d q = a.centre - n * h;
    for (int k = 0; k < 3; ++k)
      if (dot(T.n[2 + k], q) > T.d[2 + k]) return;  // beside the triangle: a neighbour's
    s.add(a.centre - n * ((a.radius + h) * 0.5), -n, a.radius - h);
    return;
  }
  if (a.type == ShapeType::capsule) {
    segment_on_face(a.core, T, 0, s);
    return;
  }
  FaceManifold fm;
  if (!face_contact(T, 0, *a.P, s.margin, fm)) return;
  for (int i = 0; i < fm.count; ++i) s.add(fm.point[i] + fm.n * (fm.depth[i] * 0.5), -fm.n, fm.depth[i]);
}

/// Whether a contact point lies on an active edge of the triangle (a vertex counts as on both
/// its edges): within `tol` of that edge's side plane.
bool on_active_edge(const SurfaceTriangle& t, const Polytope& T, const Vec3d& x, double tol) {
  for (int k = 0; k < 3; ++k)
    if ((t.active >> k & 1) && dot(T.n[2 + k], x) - T.d[2 + k] > -tol) return true;
  return false;
}

// The visitor's lowest point along -n, the triangle's normal: nothing of it comes within
// `margin` of the triangle's plane above that.
double lowest_along_normal(const SurfaceVisitor& a, const Vec3d& n) {
  if (a.type == ShapeType::sphere) return dot(n, a.centre) - a.radius;
  if (a.type == ShapeType::capsule) return std::min(dot(n, a.core.p0), dot(n, a.core.p1)) - a.radius;
  return lowest_along(*a.P, n);
}

/// The visitor against one triangle, one-sided: nothing if its centre is behind the face; the
/// general contact if its normal is the face's, or it is on an active edge and faces the front;
/// else the face's contact (an inside edge of a flat or smooth surface never pushes sideways).

int triangle_contacts(const SurfaceVisitor& a, const SurfaceTriangle& t, double margin, Polytope& T,
                      ContactPointD out[kMaxManifoldPoints]) {
  const double d0 = dot(t.n, t.v[0]);
  if (dot(t.n, a.centre) < d0) return 0;
  if (lowest_along_normal(a, t.n) - d0 > margin) return 0;  // wholly in front, beyond the margin
  make_prism(t, 2.0 * a.size + margin, T);
  if (t.active == 0) {  // no active edge: whatever the general contact, it would come to the face's
    Sink face{nullptr, margin, 0, out};
    visitor_on_face(a, T, face);
    return face.n;
  }
  Sink s{nullptr, margin, 0, out};
  visitor_vs_prism(a, T, s);
  if (s.n == 0) return 0;
  const double along = -dot(t.n, out[0].normal);
  bool keep = along >= kFaceNormalCos;
  if (!keep && along >= 0.0) {
    keep = true;
    const double tol = 1e-4 * T.size;
    for (int i = 0; i < s.n && keep; ++i) keep = on_active_edge(t, T, out[i].point, tol + std::fabs(out[i].penetration));
  }
  if (keep) return s.n;
  Sink face{nullptr, margin, 0, out};
  visitor_on_face(a, T, face);
  return face.n;
}

/// A sphere, capsule or polytope (a) against a triangle surface (b): every triangle whose
/// hierarchy leaf its box (grown by the margin) reaches, gathered and reduced to one manifold.
void visitor_vs_surface(const SurfaceVisitor& a, const ShapeView& b, const Pose& pb, Sink& s) {
  const MeshView& m = b.mesh;
  if (m.num_triangles <= 0 || !m.nodes) return;
  const Frame f = frame_of(pb);
  if (!(f.s > 0.0)) return;
  // the visitor's box in the surface's coordinates (unit scale)
  const Vec3d wc = (a.lo + a.hi) * 0.5, wh = (a.hi - a.lo) * 0.5 + Vec3d{s.margin, s.margin, s.margin};
  const Vec3d lc = f.unrotate(wc - f.t) * (1.0 / f.s);
  const Vec3d cols[3] = {f.c0, f.c1, f.c2};
  double lo[3], hi[3];
  for (int k = 0; k < 3; ++k) {
    const double h = (std::fabs(cols[k].x) * wh.x + std::fabs(cols[k].y) * wh.y + std::fabs(cols[k].z) * wh.z) / f.s;
    lo[k] = lc[k] - h, hi[k] = lc[k] + h;
  }
  Polytope T;
  Gather g;
  g.size = a.size;
  g.corners = true;
  visit_triangles_in_box(m, lo, hi, [&](int32_t t) {
    // the triangle's own box against the visitor's (a leaf holds several triangles)
    const int32_t* ix = m.triangles + 3 * t;
    for (int k = 0; k < 3; ++k) {
      const float x0 = m.vertices[3 * ix[0] + k], x1 = m.vertices[3 * ix[1] + k], x2 = m.vertices[3 * ix[2] + k];
      if (std::max({x0, x1, x2}) < lo[k] || std::min({x0, x1, x2}) > hi[k]) return true;
    }
    ContactPointD cp[kMaxManifoldPoints];
    const int n = triangle_contacts(a, triangle_of(m, f, t), s.margin, T, cp);
    g.room_for(n);
    for (int i = 0; i < n; ++i) g.add(cp[i].point, cp[i].normal, cp[i].penetration);
    return true;
  });
  g.reduce();
  for (int i = 0; i < g.count; ++i) s.add(g.pts[i], g.nrm[i], g.depth[i]);
}

void polytope_box(const Polytope& P, Vec3d& lo, Vec3d& hi) {
  lo = hi = P.v[0];
  for (int i = 1; i < P.nv; ++i) lo = min(lo, P.v[i]), hi = max(hi, P.v[i]);
}

// ---- dispatch -------------------------------------------------------------------------------

// One function per family keeps each polytope's stack scratch in its own frame.

void sphere_vs(const ShapeView& a, const Pose& pa, const ShapeView& b, const Pose& pb, Sink& s) {
  const Vec3d c = Vec3d::load(pa.position);
  const double r = double(a.radius) * pa.scale;
  switch (b.type) {
    case ShapeType::sphere:
      return sphere_sphere(c, r, Vec3d::load(pb.position), double(b.radius) * pb.scale, {0, 0, 1}, s);
    case ShapeType::capsule: {
      const Segment cb = capsule_of(b, frame_of(pb));
      return sphere_sphere(c, r, closest_on_segment(cb.p0, cb.p1, c), cb.radius,
                           any_perpendicular(cb.p1 - cb.p0), s);
    }
    case ShapeType::box:
      return sphere_box(c, r, b, frame_of(pb), s);
    case ShapeType::hull: {
      Polytope P;
      if (make_hull(b, frame_of(pb), false, P)) sphere_polytope(c, r, P, s);
      return;
    }
    case ShapeType::plane: {
      Plane pl;
      if (plane_of(b, pb, pl)) sphere_plane(c, r, pl, s);
      return;
    }
    case ShapeType::mesh:
    case ShapeType::height_field: {
      SurfaceVisitor v;
      v.type = ShapeType::sphere, v.centre = c, v.radius = r, v.size = r;
      v.lo = c - Vec3d{r, r, r}, v.hi = c + Vec3d{r, r, r};
      return visitor_vs_surface(v, b, pb, s);
    }
    case ShapeType::compound: return;  // taken apart by collide()
  }
}

void capsule_vs(const ShapeView& a, const Pose& pa, const ShapeView& b, const Pose& pb, Sink& s) {
  const Segment ca = capsule_of(a, frame_of(pa));
  switch (b.type) {
    case ShapeType::capsule:
      return capsule_capsule(ca, capsule_of(b, frame_of(pb)), s);
    case ShapeType::box:
    case ShapeType::hull: {
      Polytope P;
      if (b.type == ShapeType::box) make_box(b, frame_of(pb), P);
      else if (!make_hull(b, frame_of(pb), true, P)) return;
      return capsule_polytope(ca, P, s);
    }
    case ShapeType::plane: {
      Plane pl;
      if (plane_of(b, pb, pl)) capsule_plane(ca, pl, s);
      return;
    }
    case ShapeType::mesh:
    case ShapeType::height_field: {
      SurfaceVisitor v;
      v.type = ShapeType::capsule, v.core = ca, v.centre = (ca.p0 + ca.p1) * 0.5, v.radius = ca.radius;
      v.size = ca.radius + 0.5 * norm(ca.p1 - ca.p0);
      const Vec3d r{ca.radius, ca.radius, ca.radius};
      v.lo = min(ca.p0, ca.p1) - r, v.hi = max(ca.p0, ca.p1) + r;
      return visitor_vs_surface(v, b, pb, s);
    }
    default:
      return;
  }
}

bool make_polytope(const ShapeView& shape, const Pose& pose, bool with_edges, Polytope& P) {
  if (shape.type != ShapeType::box) return make_hull(shape, frame_of(pose), with_edges, P);
  make_box(shape, frame_of(pose), P);
  return true;
}

void polytope_vs(const ShapeView& a, const Pose& pa, const ShapeView& b, const Pose& pb, Sink& s) {
  if (b.type == ShapeType::plane) {
    Polytope A;
    Plane pl;
    if (make_polytope(a, pa, false, A) && plane_of(b, pb, pl)) polytope_plane(A, pl, s);
    return;
  }
  if (is_triangle_surface(b.type)) {
    Polytope A;
    if (!make_polytope(a, pa, true, A)) return;
    SurfaceVisitor v;
    v.type = a.type, v.P = &A, v.centre = A.centre, v.size = A.size;
    polytope_box(A, v.lo, v.hi);
    return visitor_vs_surface(v, b, pb, s);
  }
  Polytope A, B;
  if (make_polytope(a, pa, true, A) && make_polytope(b, pb, true, B)) polytope_polytope(A, B, s);
}

/// Total order on the bits of a shape and its pose; it only decides which of two same-typed
/// shapes plays a, so that collide(a, b) and collide(b, a) compute the same thing.
int compare_words(const void* x, const void* y, int n) {
  for (int i = 0; i < n; ++i) {
    uint32_t u, v;
    std::memcpy(&u, static_cast<const char*>(x) + 4 * i, 4);
    std::memcpy(&v, static_cast<const char*>(y) + 4 * i, 4);
    if (u != v) return u < v ? -1 : 1;
  }
  return 0;
}

int compare(const ShapeView& a, const Pose& pa, const ShapeView& b, const Pose& pb) {
  if (int c = compare_words(pa.position, pb.position, 3)) return c;
  if (int c = compare_words(pa.orientation, pb.orientation, 4)) return c;
  if (int c = compare_words(&pa.scale, &pb.scale, 1)) return c;
  if (int c = compare_words(&a.radius, &b.radius, 1)) return c;
  if (int c = compare_words(&a.half_height, &b.half_height, 1)) return c;
  if (int c = compare_words(a.half_extents, b.half_extents, 3)) return c;
  if (int c = compare_words(a.normal, b.normal, 3)) return c;
  if (int c = compare_words(&a.offset, &b.offset, 1)) return c;
  if (a.type != ShapeType::hull) return 0;
  const HullView &ha = a.hull, &hb = b.hull;
  if (int c = compare_words(&ha.num_vertices, &hb.num_vertices, 1)) return c;
  if (int c = compare_words(&ha.num_faces, &hb.num_faces, 1)) return c;
  if (ha.vertices && hb.vertices)
    if (int c = compare_words(ha.vertices, hb.vertices, 3 * std::min(ha.num_vertices, kMaxHullVertices))) return c;
  if (ha.planes && hb.planes)
    if (int c = compare_words(ha.planes, hb.planes, 4 * std::min(ha.num_faces, kMaxHullFaces))) return c;
  return 0;
}

/// a's type <= b's type: the pair tables only hold that half.
int collide_ordered(const ShapeView& a, const Pose& pa, const ShapeView& b, const Pose& pb, double margin,
                    ContactPoint* out) {
  Sink s{out, margin};
  switch (a.type) {
    case ShapeType::sphere: sphere_vs(a, pa, b, pb, s); break;
    case ShapeType::capsule: capsule_vs(a, pa, b, pb, s); break;
    case ShapeType::box:
    case ShapeType::hull: polytope_vs(a, pa, b, pb, s); break;
    case ShapeType::plane:  // static: nothing static collides with anything static
    case ShapeType::mesh:
    case ShapeType::height_field:
    case ShapeType::compound: break;  // taken apart by collide()
  }
  return s.n;
}

bool known(ShapeType t) { return uint32_t(t) < kNumShapeTypes; }

// ---- compounds -----------------------------------------------------------------------------

int compare_compounds(const ShapeView& a, const Pose& pa, const ShapeView& b, const Pose& pb) {
  if (int c = compare_words(pa.position, pb.position, 3)) return c;
  if (int c = compare_words(pa.orientation, pb.orientation, 4)) return c;
  if (int c = compare_words(&pa.scale, &pb.scale, 1)) return c;
  if (int c = compare_words(&a.compound.num_parts, &b.compound.num_parts, 1)) return c;
  for (int i = 0; i < a.compound.num_parts; ++i) {
    const CompoundPartView &x = a.compound.parts[i], &y = b.compound.parts[i];
    if (int c = compare_words(x.position, y.position, 3)) return c;
    if (int c = compare_words(x.orientation, y.orientation, 4)) return c;
    if (int c = compare_words(&x.scale, &y.scale, 1)) return c;
  }
  return 0;
}

/// Each part of a (a compound, or a whole shape) against each part of b, gathered and reduced
/// to one manifold, a's parts outer: the caller puts the pair in a fixed order.
int collide_parts(const ShapeView& a, const Pose& pa, const ShapeView& b, const Pose& pb, float margin, ContactPoint* out) {
  const bool ca = a.type == ShapeType::compound, cb = b.type == ShapeType::compound;
  const int na = ca ? a.compound.num_parts : 1, nb = cb ? b.compound.num_parts : 1;
  Gather g;  // its tolerances from the points' spread
  for (int i = 0; i < na; ++i) {
    const ShapeView& sa = ca ? *a.compound.parts[i].shape : a;
    const Pose qa = ca ? part_pose(pa, a.compound.parts[i]) : pa;
    for (int j = 0; j < nb; ++j) {
      const ShapeView& sb = cb ? *b.compound.parts[j].shape : b;
      const Pose qb = cb ? part_pose(pb, b.compound.parts[j]) : pb;
      ContactPoint cp[kMaxManifoldPoints];
      const int n = collide(sa, qa, sb, qb, margin, cp);
      g.room_for(n);
      for (int k = 0; k < n; ++k) g.add(Vec3d::load(cp[k].point), Vec3d::load(cp[k].normal), cp[k].penetration);
    }
  }
  g.reduce();
  Sink s{out, margin > 0.0f ? double(margin) : 0.0};  // (every point passed the parts' margin already)
  for (int i = 0; i < g.count; ++i) s.add(g.pts[i], g.nrm[i], g.depth[i]);
  return s.n;
}

}  // namespace

bool hull_supported(const HullView& h) {
  if (!hull_fits(h) || h.num_vertices < 4 || h.num_faces < 4 || h.num_edges < 6) return false;
  if (h.num_vertices - h.num_edges + h.num_faces != 2) return false;
  for (int f = 0; f < h.num_faces; ++f)
    if (h.face_start[f + 1] < h.face_start[f]) return false;
  int16_t adj[kMaxHullEdges][2];
  // Every listed edge bordered on both sides, and every loop edge listed: 2E directed edges.
  if (!edge_faces_of(h, adj) || h.face_start[h.num_faces] != 2 * h.num_edges) return false;
  for (int e = 0; e < h.num_edges; ++e)
    for (int k = 0; k < e; ++k)
      if ((h.edges[2 * e] == h.edges[2 * k] && h.edges[2 * e + 1] == h.edges[2 * k + 1]) ||
          (h.edges[2 * e] == h.edges[2 * k + 1] && h.edges[2 * e + 1] == h.edges[2 * k]))
        return false;
  Vec3d lo = Vec3d::load(h.vertices), hi = lo;
  for (int i = 1; i < h.num_vertices; ++i) {
    const Vec3d v = Vec3d::load(h.vertices + 3 * i);
    lo = min(lo, v);
    hi = max(hi, v);
  }
  const double tol = 1e-4 * norm(hi - lo);
  if (!(tol > 0.0)) return false;
  for (int f = 0; f < h.num_faces; ++f) {
    const Vec3d n = Vec3d::load(h.planes + 4 * f);
    const double d = h.planes[4 * f + 3];
    if (!(std::fabs(squared_norm(n) - 1.0) <= 1e-3)) return false;
    for (int i = 0; i < h.num_vertices; ++i)
      if (!(dot(n, Vec3d::load(h.vertices + 3 * i)) <= d + tol)) return false;
    for (int k = h.face_start[f]; k < h.face_start[f + 1]; ++k)
      if (!(std::fabs(dot(n, Vec3d::load(h.vertices + 3 * h.face_vertices[k])) - d) <= tol)) return false;
    // Counter-clockwise seen from outside: the loop's area vector points along the normal.
    Vec3d area{0, 0, 0};
    const int b = h.face_start[f], e = h.face_start[f + 1];
    for (int k = b; k < e; ++k)
      area = area + cross(Vec3d::load(h.vertices + 3 * h.face_vertices[k]),
                          Vec3d::load(h.vertices + 3 * h.face_vertices[k + 1 < e ? k + 1 : b]));
    if (!(dot(area, n) > 0.0)) return false;
  }
  return true;
}

int collide(const ShapeView& a, const Pose& pa, const ShapeView& b, const Pose& pb, float margin,
            ContactPoint out[kMaxManifoldPoints]) {
  if (!known(a.type) || !known(b.type)) return 0;
  if (a.type == ShapeType::compound || b.type == ShapeType::compound) {
    // One fixed order of the pair, as below: the compound second, or of two the lesser first.
    const bool swap = a.type != b.type ? a.type == ShapeType::compound : compare_compounds(a, pa, b, pb) > 0;
    if (!swap) return collide_parts(a, pa, b, pb, margin, out);
    const int n = collide_parts(b, pb, a, pa, margin, out);
    for (int i = 0; i < n; ++i)
      for (float& c : out[i].normal) c = -c;
    return n;
  }
  const double m = margin > 0.0f ? double(margin) : 0.0;
  const bool swap = a.type != b.type ? a.type > b.type : compare(a, pa, b, pb) > 0;
  if (!swap) return collide_ordered(a, pa, b, pb, m, out);
  const int n = collide_ordered(b, pb, a, pa, m, out);
  for (int i = 0; i < n; ++i)
    for (float& c : out[i].normal) c = -c;
  return n;
}

int collide_batch(const ShapeView* shapes_by_body, const Pose* poses, const NarrowPair* pairs, int num_pairs,
                  float margin, ContactPoint* out, int32_t* pair_of_contact, int capacity) {
  int count = 0;
  for (int p = 0; p < num_pairs; ++p) {
    const int32_t a = pairs[p].a, b = pairs[p].b;
    ContactPoint local[kMaxManifoldPoints];
    const bool room = capacity - count >= kMaxManifoldPoints;  // write in place when it surely fits
    ContactPoint* dst = room ? out + count : local;
    const int n = collide(shapes_by_body[a], poses[a], shapes_by_body[b], poses[b], margin, dst);
    if (n > capacity - count) break;
    if (!room) std::copy(local, local + n, out + count);
    if (pair_of_contact)
      for (int i = 0; i < n; ++i) pair_of_contact[count + i] = p;
    count += n;
  }
  return count;
}

}  // namespace cellphys::spu
