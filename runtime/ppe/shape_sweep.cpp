#include "runtime/ppe/shape_sweep.h"

#include "runtime/ppe/shape_distance.h"

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

}  // namespace

bool sweep_shape(const spu::ShapeView& moving, const spu::Pose& start, const Vec3d& dir, double max_dist,
                 const spu::ShapeView& target, const spu::Pose& pose, SweepHit& hit, double tolerance) {
  ConvexCore a = core_of(moving, start);
  if (target.type == spu::ShapeType::plane) return sweep_plane(a, start, dir, max_dist, target, pose, hit);
  const ConvexCore b = core_of(target, pose);
  double t = 0.0;
  for (int step = 0; step < kMaxSweepSteps; ++step) {
    a.shift = dir * t;
    const Separation s = separation(a, b);
    if (s.overlap) {
      if (t == 0.0) return at_start(start, dir, hit);
      break;  // rounding at the contact: t is still short of it
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
    t += s.lower / closing;
    if (!(t <= max_dist)) return false;
  }
  // Not converged (or overlapping by rounding): report the point reached, short of the contact.
  a.shift = dir * t;
  const Separation s = separation(a, b);
  hit.distance = t;
  hit.point = s.overlap ? a.centre() : s.point_b;
  hit.normal = s.overlap ? -dir : -s.normal;
  return true;
}

}  // namespace cellphys::ppe
