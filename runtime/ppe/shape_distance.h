// Distance between two convex shapes by GJK (Gilbert-Johnson-Keerthi) on their cores: a
// sphere is a point and a capsule a segment, each rounded by its radius; a box and a hull are
// their vertices. The exact overlap test of the world's overlap queries and the step of the
// shape sweeps (runtime/ppe/shape_sweep.h). Planes are closed forms, never GJK.
#pragma once
#include "runtime/base/vec3.h"
#include "runtime/ppe/shape_frame.h"
#include "runtime/spu/shape.h"

namespace cellphys::ppe {

/// A shape at a pose as GJK reads it: a support function and a rounding radius.
struct ConvexCore {
  enum class Kind { point, segment, box, hull };
  Kind kind = Kind::point;
  ShapeFrame frame;
  Vec3d p0{}, p1{};                     // the point, or the segment's ends (world)
  Vec3d half{};                         // box half extents (unit scale)
  const spu::HullView* hull = nullptr;  // hull vertices (unit scale)
  double radius = 0.0;                  // rounding around the core (m)
  Vec3d shift{};                        // added to every point: the core moved (sweeps)

  /// The core's point furthest along d (ties: the first vertex), world frame.
  Vec3d support(const Vec3d& d) const;
  /// A point inside the core.
  Vec3d centre() const;
};

/// The core of any shape but a plane (a plane has no support point).
ConvexCore core_of(const spu::ShapeView& shape, const spu::Pose& pose);

struct Separation {
  /// The solids share a point: the cores' Minkowski difference holds the origin (to a relative
  /// 1e-12 of the shapes' size), or the cores are closer than the radii.
  bool overlap = false;
  double distance = 0.0;  // between the surfaces when apart (m)
  /// A lower bound on `distance` from GJK's last separating plane, within a relative 1e-10
  /// of it: how far a sweep may advance without passing the first contact.
  double lower = 0.0;
  Vec3d normal{};              // unit, from a towards b, when the cores are apart
  Vec3d point_a{}, point_b{};  // the closest surface points, when apart
};

/// One triangle of a mesh or height field as a core: a three-vertex hull about its centroid,
/// in world coordinates. It holds the vertices its core points at, so it stays where it is.
struct TriangleCore {
  TriangleCore(const ShapeFrame& surface, const spu::MeshView& m, int32_t triangle);
  TriangleCore(const TriangleCore&) = delete;
  TriangleCore& operator=(const TriangleCore&) = delete;
  Vec3d v[3];     // world vertices
  Vec3d normal;   // world front normal
  ConvexCore core;

 private:
  float local_[9];
  spu::HullView view_;
};

/// The world box of a core with its radius.
void core_box(const ConvexCore& c, Vec3d& lo, Vec3d& hi);

/// The box, in a surface's unit-scale coordinates, that holds the world box [lo, hi].
void box_in_surface(const ShapeFrame& surface, const Vec3d& lo, const Vec3d& hi, double out_lo[3], double out_hi[3]);

/// Distance between a and b (GJK, at most 64 iterations, in double precision).
Separation separation(const ConvexCore& a, const ConvexCore& b);

/// Whether two shapes at their poses overlap (either may be a plane; two planes never do).
bool shapes_overlap(const spu::ShapeView& a, const spu::Pose& pa, const spu::ShapeView& b, const spu::Pose& pb);

/// A plane shape in the world frame: n.x <= offset, n unit, the pose's scale on the offset (as
/// in the narrow phase). False for a zero normal.
bool world_plane(const spu::ShapeView& plane, const spu::Pose& pose, Vec3d& n, double& offset);

}  // namespace cellphys::ppe
