// Exact ray casts against one shape at a pose: sphere, capsule, box, hull (its face planes,
// Cyrus-Beck clipping), plane, and the triangles of a mesh or height field (through its
// hierarchy), in double precision, with the pose's uniform scale. The world's ray queries (World::ray_cast, runtime/ppe/world_queries.cpp) call these on the bodies
// their tree leaves, and the tests call them on every body.
#pragma once
#include "runtime/base/vec3.h"
#include "runtime/spu/shape.h"

namespace cellphys::ppe {

struct ShapeRayHit {
  double distance = 0.0;  // along the unit direction from the origin (m)
  Vec3d point{}, normal{};  // world; the normal is the shape's outward unit normal there
};

/// The first point of `shape` at `pose` on origin + t dir, 0 <= t <= max_dist (dir unit, both
/// finite, max_dist may be infinite). A ray starting inside or on the solid hits at 0, at its
/// origin, with normal -dir: it is already in the shape. A plane is the half-space n.x <=
/// offset (world frame, the pose's scale applies to the offset, as in the narrow phase). A
/// mesh or height field is one-sided: only a triangle's front is hit (a ray from behind passes).
/// False when the ray misses within max_dist.
bool ray_shape(const spu::ShapeView& shape, const spu::Pose& pose, const Vec3d& origin, const Vec3d& dir,
               double max_dist, ShapeRayHit& hit);

}  // namespace cellphys::ppe
