#include "runtime/ppe/shape_sweep.h"

#include <algorithm>
#include <cmath>

#include "runtime/ppe/shape_distance.h"
#include "runtime/spu/narrow_phase.h"
#include "runtime/spu/surface_tree.h"

namespace cellphys::ppe {

namespace {

bool at_start(const spu::Pose& start, const Vec3d& dir, SweepHit& hit) {
  hit.distance = 0.0;
  hit.point = Vec3d::load(start.position);
  hit.normal = -dir;
  return true;
}

// The moving shape's lowest point along -n reaches the surface n.x = c.
bool sweep_plane(const ConvexCore& a, const spu::Pose& start, const Vec3d& dir, double max_dist,
                 const spu::ShapeView& plane, const spu::Pose& pose, SweepHit& hit) {
  Vec3d n;
  double c;
  if (!world_plane(plane, pose, n, c)) return false;
  const Vec3d low = a.support(-n) - n * a.radius;
  const double height = dot(n, low) - c;
  if (height < 0.0) return at_start(start, dir, hit);
  const double closing = -dot(n, dir);
  if (!(closing > 0.0)) return false;  // touching and sliding along, or moving away
  const double t = height / closing;
  if (!(t <= max_dist)) return false;
  hit.distance = t;
  hit.point = low + dir * t;
  hit.normal = n;
  return true;
}

// Shapes that touch at the start (GJK sees no gap): the narrow phase's deepest contact says
// whether they overlap by more than the tolerance (then the sweep starts inside) or only touch,
// when its normal decides: moving into the surface hits at 0, moving off or along it misses.
bool starts_in_contact(const spu::ShapeView& moving, const spu::Pose& start, const Vec3d& dir,
                       const spu::ShapeView& target, const spu::Pose& pose, double tolerance, SweepHit& hit) {
  spu::ContactPoint cp[spu::kMaxManifoldPoints];
  const int n = spu::collide(moving, start, target, pose, float(tolerance), cp);
  int deepest = -1;
  for (int i = 0; i < n; ++i)
    if (deepest < 0 || cp[i].penetration > cp[deepest].penetration) deepest = i;
  if (deepest < 0 || cp[deepest].penetration > tolerance) return at_start(start, dir, hit);
  const Vec3d normal = Vec3d::load(cp[deepest].normal);  // from the moving shape to the target
  if (!(dot(dir, normal) > 0.0)) return false;
  hit.distance = 0.0;
  hit.point = Vec3d::load(cp[deepest].point);
  hit.normal = -normal;
  return true;
}


// Conservative advancement of core a against core b (the target's, or one triangle's).
bool sweep_cores(ConvexCore a, const ConvexCore& b, const spu::ShapeView& moving, const spu::Pose& start,
                 const Vec3d& dir, double max_dist, const spu::ShapeView& target, const spu::Pose& pose,
                 double tolerance, SweepHit& hit) {
  double t = 0.0;
  Separation last;
  for (int step = 0; step < kMaxSweepSteps; ++step) {
    a.shift = dir * t;
    const Separation s = separation(a, b);
    if (s.overlap) {
      if (t == 0.0) return starts_in_contact(moving, start, dir, target, pose, tolerance, hit);
      // Rounding at the contact (t is still short of it): the last separated step's surface.
      hit.distance = t;
      hit.point = last.point_b;
      hit.normal = -last.normal;
      return true;
    }
    // A separating plane the motion does not close on separates them along the whole line,
    // however near they are (a shape resting on another and moving off it misses).
    const double closing = dot(dir, s.normal);
    if (!(closing > 0.0)) return false;
    if (s.lower <= tolerance) {
      hit.distance = t;
      hit.point = s.point_b;
      hit.normal = -s.normal;
      return true;
    }
    // Half the tolerance short of the plane: the next step finds them apart, within it.
    t += (s.lower - 0.5 * tolerance) / closing;
    if (!(t <= max_dist)) return false;
    last = s;
  }
  // Not converged: report the point reached, short of the contact.
  hit.distance = t;
  hit.point = last.point_b;
  hit.normal = -last.normal;
  return true;
}

// A triangle surface, one-sided: the first triangle met whose front faces the motion and has
// the moving shape in front of it, among those the swept box reaches.
bool sweep_surface(const spu::ShapeView& moving, const spu::Pose& start, const Vec3d& dir, double max_dist,
                   const spu::ShapeView& target, const spu::Pose& pose, SweepHit& hit, double tolerance) {
  const spu::MeshView& m = target.mesh;
  const ShapeFrame f = ShapeFrame::of(pose);
  if (!(f.s > 0.0) || !std::isfinite(max_dist)) return false;
  const ConvexCore a = core_of(moving, start);
  // the swept shape's box, in the surface's unit-scale coordinates
  Vec3d lo, hi;
  core_box(a, lo, hi);
  const Vec3d move = dir * max_dist, pad{tolerance, tolerance, tolerance};
  lo = min(lo, lo + move) - pad, hi = max(hi, hi + move) + pad;
  double blo[3], bhi[3];
  box_in_surface(f, lo, hi, blo, bhi);
  bool found = false;
  double reach = max_dist;
  const Vec3d centre = a.centre();
  spu::visit_triangles_in_box(m, blo, bhi, [&](int32_t t) {
    const TriangleCore tri(f, m, t);
    if (!(dot(tri.normal, dir) < 0.0) || dot(tri.normal, centre - tri.v[0]) < 0.0) return true;  // moving off its front, or behind it
    SweepHit h;
    if (sweep_cores(a, tri.core, moving, start, dir, reach, target, pose, tolerance, h) && (!found || h.distance < hit.distance)) {
      hit = h, found = true, reach = h.distance;
      if (h.distance == 0.0) return false;  // nothing comes sooner
    }
    return true;
  });
  return found;
}

}  // namespace

bool sweep_shape(const spu::ShapeView& moving, const spu::Pose& start, const Vec3d& dir, double max_dist,
                 const spu::ShapeView& target, const spu::Pose& pose, SweepHit& hit, double tolerance) {
  if (target.type == spu::ShapeType::plane) return sweep_plane(core_of(moving, start), start, dir, max_dist, target, pose, hit);
  if (spu::is_triangle_surface(target.type)) return sweep_surface(moving, start, dir, max_dist, target, pose, hit, tolerance);
  if (target.type == spu::ShapeType::compound) {  // the first part met
    bool found = false;
    for (int i = 0; i < target.compound.num_parts; ++i) {
      const spu::CompoundPartView& part = target.compound.parts[i];
      SweepHit h;
      if (sweep_shape(moving, start, dir, found ? hit.distance : max_dist, *part.shape, spu::part_pose(pose, part), h,
                      tolerance) &&
          (!found || h.distance < hit.distance))
        hit = h, found = true;
    }
    return found;
  }
  return sweep_cores(core_of(moving, start), core_of(target, pose), moving, start, dir, max_dist, target, pose, tolerance, hit);
}

}  // namespace cellphys::ppe
