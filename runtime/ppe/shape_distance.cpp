#include "runtime/ppe/shape_distance.h"

#include "runtime/spu/surface_tree.h"

#include <algorithm>
#include <cmath>

namespace cellphys::ppe {

namespace {

constexpr int kMaxIterations = 64;
constexpr double kRelativeGap = 1e-10;  // GJK stops when |v|^2 - v.w <= this times |v|^2

// A simplex vertex: w = a - b with the support points of each core that made it.
struct Vertex {
  Vec3d w, a, b;
};

struct Simplex {
  Vertex v[4];
  double weight[4];
  int n = 0;
};

// Keeps vertices `keep` (indices) with their weights, in that order.
void reduce(Simplex& s, std::initializer_list<int> keep, std::initializer_list<double> weights) {
  Vertex v[4];
  double l[4];
  int n = 0;
  auto wi = weights.begin();
  for (int k : keep) v[n] = s.v[k], l[n] = *wi++, ++n;
  for (int k = 0; k < n; ++k) s.v[k] = v[k], s.weight[k] = l[k];
  s.n = n;
}

// Closest point of triangle (i, j, k) of s to the origin (Ericson, Real-Time Collision
// Detection 5.1.5), as the vertices it needs and their weights. Leaves s untouched; writes
// the reduced simplex to out.
void closest_triangle(const Simplex& s, int i, int j, int k, Simplex& out) {
  const Vec3d a = s.v[i].w, b = s.v[j].w, c = s.v[k].w;
  const Vec3d ab = b - a, ac = c - a;
  out = s;
  const double d1 = -dot(ab, a), d2 = -dot(ac, a);
  if (d1 <= 0.0 && d2 <= 0.0) return reduce(out, {i}, {1.0});
  const double d3 = -dot(ab, b), d4 = -dot(ac, b);
  if (d3 >= 0.0 && d4 <= d3) return reduce(out, {j}, {1.0});
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) {
    const double t = d1 / (d1 - d3);
    return reduce(out, {i, j}, {1.0 - t, t});
  }
  const double d5 = -dot(ab, c), d6 = -dot(ac, c);
  if (d6 >= 0.0 && d5 <= d6) return reduce(out, {k}, {1.0});
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) {
    const double t = d2 / (d2 - d6);
    return reduce(out, {i, k}, {1.0 - t, t});
  }
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0) {
    const double t = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    return reduce(out, {j, k}, {1.0 - t, t});
  }
  const double inv = 1.0 / (va + vb + vc);
  const double v = vb * inv, w = vc * inv;
  reduce(out, {i, j, k}, {1.0 - v - w, v, w});
}

Vec3d point_of(const Simplex& s) {
  Vec3d p{};
  for (int k = 0; k < s.n; ++k) p = p + s.v[k].w * s.weight[k];
  return p;
}

// The simplex reduced to the smallest face holding its closest point to the origin. Returns
// false when a full tetrahedron holds the origin.
bool closest(Simplex& s) {
  switch (s.n) {
    case 1: s.weight[0] = 1.0; return true;
    case 2: {
      const Vec3d a = s.v[0].w, ab = s.v[1].w - a;
      const double len2 = squared_norm(ab);
      const double t = len2 > 0.0 ? -dot(a, ab) / len2 : 0.0;
      if (t <= 0.0) reduce(s, {0}, {1.0});
      else if (t >= 1.0) reduce(s, {1}, {1.0});
      else reduce(s, {0, 1}, {1.0 - t, t});
      return true;
    }
    case 3: {
      Simplex out;
      closest_triangle(s, 0, 1, 2, out);
      s = out;
      return true;
    }
    default: {
      // The faces with the origin outside them (on the other side from the fourth vertex);
      // a flat tetrahedron has no inside, so every face is tried.
      static constexpr int kFaces[4][4] = {{0, 1, 2, 3}, {0, 2, 3, 1}, {0, 3, 1, 2}, {1, 3, 2, 0}};
      double best = -1.0;
      Simplex chosen;
      for (const auto& f : kFaces) {
        const Vec3d a = s.v[f[0]].w;
        const Vec3d n = cross(s.v[f[1]].w - a, s.v[f[2]].w - a);
        const Vec3d to_opposite = s.v[f[3]].w - a;
        const double side_o = -dot(a, n), side_d = dot(to_opposite, n);
        const bool flat = std::fabs(side_d) <= 1e-12 * norm(n) * norm(to_opposite);
        if (!flat && side_o * side_d >= 0.0) continue;  // the origin is on the inner side
        Simplex out;
        closest_triangle(s, f[0], f[1], f[2], out);
        const double d = squared_norm(point_of(out));
        if (best < 0.0 || d < best) best = d, chosen = out;
      }
      if (best < 0.0) return false;
      s = chosen;
      return true;
    }
  }
}

}  // namespace

Vec3d ConvexCore::support(const Vec3d& d) const {
  switch (kind) {
    case Kind::point: return p0 + shift;
    case Kind::segment: return (dot(d, p1 - p0) > 0.0 ? p1 : p0) + shift;
    case Kind::box: {
      const Vec3d l = frame.unrotate(d);
      return frame.to_world({l.x >= 0.0 ? half.x : -half.x, l.y >= 0.0 ? half.y : -half.y,
                             l.z >= 0.0 ? half.z : -half.z}) + shift;
    }
    case Kind::hull: {
      const Vec3d l = frame.unrotate(d);
      int best = 0;
      double top = dot(l, Vec3d::load(hull->vertices));
      for (int i = 1; i < hull->num_vertices; ++i) {
        const double h = dot(l, Vec3d::load(hull->vertices + 3 * i));
        if (h > top) top = h, best = i;
      }
      return frame.to_world(Vec3d::load(hull->vertices + 3 * best)) + shift;
    }
  }
  return p0 + shift;
}

Vec3d ConvexCore::centre() const {
  if (kind == Kind::point) return p0 + shift;
  if (kind == Kind::segment) return (p0 + p1) * 0.5 + shift;
  return frame.t + shift;  // boxes and hulls are centred on their centre of mass
}

ConvexCore core_of(const spu::ShapeView& shape, const spu::Pose& pose) {
  ConvexCore c;
  c.frame = ShapeFrame::of(pose);
  const double s = c.frame.s;
  switch (shape.type) {
    case spu::ShapeType::sphere:
      c.kind = ConvexCore::Kind::point;
      c.p0 = c.frame.t;
      c.radius = double(shape.radius) * s;
      break;
    case spu::ShapeType::capsule: {
      c.kind = ConvexCore::Kind::segment;
      const Vec3d h = c.frame.rotate({0, 0, double(shape.half_height) * s});
      c.p0 = c.frame.t - h, c.p1 = c.frame.t + h;
      c.radius = double(shape.radius) * s;
      break;
    }
    case spu::ShapeType::box:
      c.kind = ConvexCore::Kind::box;
      c.half = Vec3d::load(shape.half_extents);
      break;
    case spu::ShapeType::hull:
      c.kind = ConvexCore::Kind::hull;
      c.hull = &shape.hull;
      break;
    case spu::ShapeType::plane:  // callers take planes and triangle surfaces apart
    case spu::ShapeType::mesh:
    case spu::ShapeType::height_field:
    case spu::ShapeType::compound: break;
  }
  return c;
}

Separation separation(const ConvexCore& a, const ConvexCore& b) {
  Separation out;
  Simplex s;
  Vec3d v = a.centre() - b.centre();
  if (squared_norm(v) == 0.0) v = {1, 0, 0};
  double lower = 0.0, scale2 = 0.0;  // scale2: the largest |w|^2 seen, for the zero test
  bool apart = false;  // a separating plane was found
  for (int it = 0; it < kMaxIterations; ++it) {
    Vertex x;
    x.a = a.support(-v), x.b = b.support(v), x.w = x.a - x.b;
    scale2 = std::max(scale2, squared_norm(x.w));
    const double vv = squared_norm(v), vw = dot(v, x.w);
    if (s.n > 0) {
      if (vw > 0.0) lower = std::max(lower, vw / std::sqrt(vv)), apart = true;
      if (vv - vw <= kRelativeGap * vv) break;  // w adds nothing: v is the closest point
      bool repeat = false;
      for (int k = 0; k < s.n; ++k) repeat = repeat || (s.v[k].w.x == x.w.x && s.v[k].w.y == x.w.y && s.v[k].w.z == x.w.z);
      if (repeat) break;
    }
    s.v[s.n++] = x;
    if (!closest(s)) {
      out.overlap = true;
      return out;
    }
    const Vec3d next = point_of(s);
    const double nn = squared_norm(next);
    if (nn <= 1e-24 * scale2) break;  // the origin on the simplex: touching
    if (s.n > 1 && nn >= vv) break;  // no progress: rounding
    v = next;
  }
  // Without a separating plane the cores touch or overlap (GJK's rounding can stall just short
  // of enclosing the origin when they overlap).
  if (!apart) {
    out.overlap = true;
    return out;
  }
  Vec3d pa{}, pb{};
  for (int k = 0; k < s.n; ++k) pa = pa + s.v[k].a * s.weight[k], pb = pb + s.v[k].b * s.weight[k];
  const Vec3d d = pb - pa;
  const double core = norm(d);
  const double radii = a.radius + b.radius;
  out.overlap = !(core > radii);
  if (out.overlap) return out;
  out.normal = d * (1.0 / core);
  out.point_a = pa + out.normal * a.radius;
  out.point_b = pb - out.normal * b.radius;
  out.distance = core - radii;
  out.lower = std::min(lower, core) - radii;
  return out;
}

bool world_plane(const spu::ShapeView& plane, const spu::Pose& pose, Vec3d& n, double& offset) {
  n = Vec3d::load(plane.normal);
  const double l = norm(n);
  if (!(l > 0.0)) return false;
  n = n * (1.0 / l);
  offset = double(plane.offset) / l * double(pose.scale);
  return true;
}

TriangleCore::TriangleCore(const ShapeFrame& f, const spu::MeshView& m, int32_t t) {
  const int32_t* ix = m.triangles + 3 * t;
  for (int c = 0; c < 3; ++c) v[c] = f.to_world(Vec3d::load(m.vertices + 3 * ix[c]));
  normal = f.rotate(Vec3d::load(m.normals + 3 * t));
  const Vec3d mid = (v[0] + v[1] + v[2]) * (1.0 / 3.0);
  for (int c = 0; c < 3; ++c)
    for (int k = 0; k < 3; ++k) local_[3 * c + k] = float(v[c][k] - mid[k]);
  view_.num_vertices = 3;
  view_.vertices = local_;
  spu::Pose at;
  for (int k = 0; k < 3; ++k) at.position[k] = float(mid[k]);
  core.kind = ConvexCore::Kind::hull;
  core.frame = ShapeFrame::of(at);
  core.hull = &view_;
}

void core_box(const ConvexCore& c, Vec3d& lo, Vec3d& hi) {
  const Vec3d x{1, 0, 0}, y{0, 1, 0}, z{0, 0, 1};
  lo = Vec3d{c.support(-x).x, c.support(-y).y, c.support(-z).z} - Vec3d{c.radius, c.radius, c.radius};
  hi = Vec3d{c.support(x).x, c.support(y).y, c.support(z).z} + Vec3d{c.radius, c.radius, c.radius};
}

void box_in_surface(const ShapeFrame& f, const Vec3d& lo, const Vec3d& hi, double out_lo[3], double out_hi[3]) {
  const Vec3d wc = (lo + hi) * 0.5, wh = (hi - lo) * 0.5, lc = f.to_shape(wc);
  for (int k = 0; k < 3; ++k) {
    const double h = (std::fabs(f.R.m[0][k]) * wh.x + std::fabs(f.R.m[1][k]) * wh.y + std::fabs(f.R.m[2][k]) * wh.z) / f.s;
    out_lo[k] = lc[k] - h, out_hi[k] = lc[k] + h;
  }
}

namespace {

// A convex shape and a triangle surface overlap where the shape reaches any triangle (either
// side: an overlap test asks what is there, not what collides).
bool overlaps_surface(const spu::ShapeView& a, const spu::Pose& pa, const spu::ShapeView& surface, const spu::Pose& ps) {
  const ShapeFrame f = ShapeFrame::of(ps);
  if (!(f.s > 0.0)) return false;
  const ConvexCore k = core_of(a, pa);
  Vec3d lo, hi;
  core_box(k, lo, hi);
  double blo[3], bhi[3];
  box_in_surface(f, lo, hi, blo, bhi);
  bool hit = false;
  spu::visit_triangles_in_box(surface.mesh, blo, bhi, [&](int32_t t) {
    const TriangleCore tri(f, surface.mesh, t);
    hit = separation(k, tri.core).overlap;
    return !hit;
  });
  return hit;
}

}  // namespace

bool shapes_overlap(const spu::ShapeView& a, const spu::Pose& pa, const spu::ShapeView& b, const spu::Pose& pb) {
  if (a.type == spu::ShapeType::compound || b.type == spu::ShapeType::compound) {  // any part
    const bool first = a.type == spu::ShapeType::compound;
    const spu::ShapeView& c = first ? a : b;
    const spu::Pose& pc = first ? pa : pb;
    for (int i = 0; i < c.compound.num_parts; ++i) {
      const spu::CompoundPartView& part = c.compound.parts[i];
      const spu::Pose q = spu::part_pose(pc, part);
      if (first ? shapes_overlap(*part.shape, q, b, pb) : shapes_overlap(a, pa, *part.shape, q)) return true;
    }
    return false;
  }
  const bool a_surface = spu::is_triangle_surface(a.type), b_surface = spu::is_triangle_surface(b.type);
  if (a_surface || b_surface) {
    if ((a_surface && b_surface) || a.type == spu::ShapeType::plane || b.type == spu::ShapeType::plane) return false;
    return a_surface ? overlaps_surface(b, pb, a, pa) : overlaps_surface(a, pa, b, pb);
  }
  const bool a_plane = a.type == spu::ShapeType::plane, b_plane = b.type == spu::ShapeType::plane;
  if (a_plane && b_plane) return false;
  if (a_plane || b_plane) {
    Vec3d n;
    double c;
    if (!world_plane(a_plane ? a : b, a_plane ? pa : pb, n, c)) return false;
    const ConvexCore k = b_plane ? core_of(a, pa) : core_of(b, pb);
    return dot(n, k.support(-n)) - k.radius < c;  // the shape's lowest point below the surface
  }
  return separation(core_of(a, pa), core_of(b, pb)).overlap;
}

}  // namespace cellphys::ppe
