#include "runtime/ppe/shape_ray.h"

#include <cmath>
#include <limits>

#include "runtime/ppe/shape_distance.h"
#include "runtime/ppe/shape_frame.h"
#include "runtime/spu/surface_tree.h"

namespace cellphys::ppe {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// A hit at 0: the ray starts in the solid.
bool inside(const Vec3d& origin, const Vec3d& dir, ShapeRayHit& hit) {
  hit.distance = 0.0;
  hit.point = origin;
  hit.normal = -dir;
  return true;
}

// First entry t >= 0 into the ball |x - c| <= r from an origin outside it.
bool ray_ball(const Vec3d& o, const Vec3d& d, const Vec3d& c, double r, double& t) {
  const Vec3d m = o - c;
  const double b = dot(m, d), cc = dot(m, m) - r * r;
  if (b > 0.0) return false;  // outside and pointing away
  const double disc = b * b - cc;
  if (disc < 0.0) return false;
  t = -b - std::sqrt(disc);
  if (t < 0.0) t = 0.0;
  return true;
}

bool ray_sphere(const spu::ShapeView& v, const spu::Pose& p, const Vec3d& o, const Vec3d& d, double max_dist,
                ShapeRayHit& hit) {
  const Vec3d c = Vec3d::load(p.position);
  const double r = double(v.radius) * p.scale;
  if (squared_norm(o - c) <= r * r) return inside(o, d, hit);
  double t;
  if (!ray_ball(o, d, c, r, t) || t > max_dist) return false;
  hit.distance = t;
  hit.point = o + d * t;
  const Vec3d n = hit.point - c;
  const double l = norm(n);
  hit.normal = l > 0.0 ? n * (1.0 / l) : -d;
  return true;
}

// The capsule is the union of its finite cylinder and two end balls: from outside, its first
// hit is the earliest of the cylinder's side (within the core's length) and the balls.
bool ray_capsule(const spu::ShapeView& v, const spu::Pose& p, const Vec3d& o, const Vec3d& d, double max_dist,
                 ShapeRayHit& hit) {
  const ShapeFrame f = ShapeFrame::of(p);
  const Vec3d a = f.rotate({0, 0, 1});
  const double h = double(v.half_height) * f.s, r = double(v.radius) * f.s;
  const Vec3d p0 = f.t - a * h, p1 = f.t + a * h;
  const Vec3d m = o - p0;
  const double along = std::min(std::max(dot(m, a), 0.0), 2.0 * h);
  if (squared_norm(m - a * along) <= r * r) return inside(o, d, hit);

  double best = kInf;
  Vec3d normal{};
  const Vec3d dp = d - a * dot(d, a), mp = m - a * dot(m, a);  // across the axis
  const double A = dot(dp, dp), B = dot(mp, dp), C = dot(mp, mp) - r * r;
  if (A > 0.0 && B < 0.0) {
    const double disc = B * B - A * C;
    if (disc >= 0.0) {
      const double t = std::max((-B - std::sqrt(disc)) / A, 0.0);
      const double s = dot(m, a) + t * dot(d, a);
      if (s >= 0.0 && s <= 2.0 * h) best = t, normal = (mp + dp * t) * (1.0 / r);
    }
  }
  const Vec3d ends[2] = {p0, p1};
  for (const Vec3d& c : ends) {
    double t;
    if (ray_ball(o, d, c, r, t) && t < best) best = t, normal = (o + d * t - c) * (1.0 / r);
  }
  if (best == kInf || !(best <= max_dist)) return false;
  hit.distance = best;
  hit.point = o + d * best;
  const double l = norm(normal);
  hit.normal = l > 0.0 ? normal * (1.0 / l) : -d;
  return true;
}

// Entry into the intersection of half-spaces n.x <= c (shape coordinates) from an origin
// outside it: Cyrus-Beck clipping. `plane` gives face k's normal and offset. Returns the face
// entered through, or -1 for a miss within max_t.
template <class Plane>
int clip_convex(int faces, const Plane& plane, const Vec3d& o, const Vec3d& d, double max_t, double& t_in) {
  double enter = -kInf, leave = max_t;
  int face = -1;
  for (int k = 0; k < faces; ++k) {
    Vec3d n;
    double c;
    plane(k, n, c);
    const double denom = dot(n, d), gap = c - dot(n, o);  // gap < 0: origin outside face k
    if (denom == 0.0) {
      if (gap < 0.0) return -1;  // parallel to a face it is outside of
      continue;
    }
    const double t = gap / denom;
    if (denom < 0.0) {
      if (t > enter) enter = t, face = k;
    } else if (t < leave) {
      leave = t;
    }
    if (enter > leave) return -1;
  }
  // Outside some face: if that face is entered, enter > 0; if it is left, leave < 0.
  if (face < 0 || enter < 0.0 || leave < 0.0) return -1;
  t_in = enter;
  return face;
}

bool ray_polytope(bool is_box, const spu::ShapeView& v, const spu::Pose& p, const Vec3d& o, const Vec3d& d,
                  double max_dist, ShapeRayHit& hit) {
  const ShapeFrame f = ShapeFrame::of(p);
  const Vec3d ol = f.to_shape(o), dl = f.unrotate(d);  // dl is unit: t in shape units is t / s
  bool in = true;
  Vec3d nk;
  double ck;
  auto plane = [&](int k, Vec3d& n, double& c) {
    if (is_box) {
      const int axis = k >> 1;
      const double sign = (k & 1) ? 1.0 : -1.0;
      n = {axis == 0 ? sign : 0.0, axis == 1 ? sign : 0.0, axis == 2 ? sign : 0.0};
      c = v.half_extents[axis];
    } else {
      n = Vec3d::load(v.hull.planes + 4 * k);
      c = v.hull.planes[4 * k + 3];
    }
  };
  const int faces = is_box ? 6 : v.hull.num_faces;
  for (int k = 0; k < faces && in; ++k) {
    plane(k, nk, ck);
    in = dot(nk, ol) <= ck;
  }
  if (in) return inside(o, d, hit);
  double t;
  const int face = clip_convex(faces, plane, ol, dl, max_dist / f.s, t);
  if (face < 0) return false;
  hit.distance = t * f.s;
  if (!(hit.distance <= max_dist)) return false;
  hit.point = o + d * hit.distance;
  plane(face, nk, ck);
  hit.normal = f.rotate(nk * (1.0 / norm(nk)));  // a hull's stored normals are unit to float precision
  return true;
}

bool ray_plane(const spu::ShapeView& v, const spu::Pose& p, const Vec3d& o, const Vec3d& d, double max_dist,
               ShapeRayHit& hit) {
  Vec3d n;
  double c;
  if (!world_plane(v, p, n, c)) return false;
  const double gap = c - dot(n, o);
  if (gap >= 0.0) return inside(o, d, hit);
  const double denom = dot(n, d);
  if (denom >= 0.0) return false;
  const double t = gap / denom;
  if (!(t <= max_dist)) return false;
  hit.distance = t;
  hit.point = o + d * t;
  hit.normal = n;
  return true;
}

// A triangle surface is one-sided: the ray hits a triangle's front only (Moller-Trumbore in the
// surface's unit-scale coordinates), the first such hit along the ray; no hit from behind.
bool ray_surface(const spu::ShapeView& v, const spu::Pose& p, const Vec3d& o, const Vec3d& d, double max_dist,
                 ShapeRayHit& hit) {
  const spu::MeshView& m = v.mesh;
  const ShapeFrame f = ShapeFrame::of(p);
  if (!(f.s > 0.0)) return false;
  const Vec3d lo = f.to_shape(o), ld = f.unrotate(d);  // unit: distances in the surface's units are / s
  const double lo3[3] = {lo.x, lo.y, lo.z}, ld3[3] = {ld.x, ld.y, ld.z};
  double best = max_dist / f.s;
  int best_t = -1;
  spu::visit_triangles_on_ray(m, lo3, ld3, best, [&](int32_t t) {
    const int32_t* ix = m.triangles + 3 * t;
    const Vec3d a = Vec3d::load(m.vertices + 3 * ix[0]), b = Vec3d::load(m.vertices + 3 * ix[1]),
                c = Vec3d::load(m.vertices + 3 * ix[2]);
    const Vec3d e1 = b - a, e2 = c - a, q = cross(ld, e2);
    const double det = dot(e1, q);
    if (!(det < 0.0) && !(det > 0.0)) return true;
    if (dot(Vec3d::load(m.normals + 3 * t), ld) >= 0.0) return true;  // from behind, or along it
    const double inv = 1.0 / det;
    const Vec3d sv = lo - a;
    const double u = dot(sv, q) * inv;
    if (u < 0.0 || u > 1.0) return true;
    const Vec3d r = cross(sv, e1);
    const double w = dot(ld, r) * inv;
    if (w < 0.0 || u + w > 1.0) return true;
    const double at = dot(e2, r) * inv;
    if (at >= 0.0 && at < best) best = at, best_t = t;  // ties: the first in the tree's order
    return true;
  });
  if (best_t < 0) return false;
  hit.distance = best * f.s;
  hit.point = o + d * hit.distance;
  hit.normal = f.rotate(Vec3d::load(m.normals + 3 * best_t));
  return true;
}

}  // namespace

bool ray_shape(const spu::ShapeView& shape, const spu::Pose& pose, const Vec3d& origin, const Vec3d& dir,
               double max_dist, ShapeRayHit& hit) {
  switch (shape.type) {
    case spu::ShapeType::sphere: return ray_sphere(shape, pose, origin, dir, max_dist, hit);
    case spu::ShapeType::capsule: return ray_capsule(shape, pose, origin, dir, max_dist, hit);
    case spu::ShapeType::box: return ray_polytope(true, shape, pose, origin, dir, max_dist, hit);
    case spu::ShapeType::hull: return ray_polytope(false, shape, pose, origin, dir, max_dist, hit);
    case spu::ShapeType::plane: return ray_plane(shape, pose, origin, dir, max_dist, hit);
    case spu::ShapeType::mesh:
    case spu::ShapeType::height_field: return ray_surface(shape, pose, origin, dir, max_dist, hit);
    case spu::ShapeType::compound: {  // the first part hit (ties: the first part)
      bool found = false;
      for (int i = 0; i < shape.compound.num_parts; ++i) {
        ShapeRayHit h;
        const spu::CompoundPartView& part = shape.compound.parts[i];
        if (ray_shape(*part.shape, spu::part_pose(pose, part), origin, dir, found ? hit.distance : max_dist, h) &&
            (!found || h.distance < hit.distance))
          hit = h, found = true;
      }
      return found;
    }
  }
  return false;
}

}  // namespace cellphys::ppe
