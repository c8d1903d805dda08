// A shape swept along a straight line to its first contact with another (translation only).
//
// Conservative advancement on GJK's separating plane (runtime/ppe/shape_distance.h): each
// step moves the shape by (gap - tolerance / 2) / (dir . n), where gap is the lower bound on
// the distance from the plane GJK found and n its normal; no point of the moving shape can
// cross that plane sooner, so the sweep never passes the true first contact. It stops when the
// gap is at most `tolerance`: the reported distance is then at most the true first-contact
// distance, and the shapes there are at most `tolerance` apart (a shape grazing a surface
// closer than the tolerance counts as touching it). Against a plane the sweep is a closed form.
#pragma once
#include "runtime/base/vec3.h"
#include "runtime/spu/shape.h"

namespace cellphys::ppe {

inline constexpr double kSweepTolerance = 1e-5;  // m
inline constexpr int kMaxSweepSteps = 64;

struct SweepHit {
  double distance = 0.0;  // how far the moving shape travels along the unit direction (m)
  Vec3d point{};          // on the surface of the shape hit (world)
  Vec3d normal{};         // that surface's outward unit normal there (towards the moving shape)
};

/// The first contact of `moving` (any shape but a plane) starting at `start` and moving along
/// the unit `dir` up to max_dist, with `target` at `pose` (a plane too). A moving shape that
/// starts overlapping (by more than the tolerance, as the narrow phase measures a start with no
/// gap) hits at 0, at its start position, with normal -dir; one starting touching or within
/// the tolerance hits at 0 with that surface's normal, unless it moves away from the surface
/// or along it (a box resting on the ground and lifted misses the ground). False for a miss
/// within max_dist. After kMaxSweepSteps steps without meeting the tolerance it reports where
/// it got to (never past the contact).
bool sweep_shape(const spu::ShapeView& moving, const spu::Pose& start, const Vec3d& dir, double max_dist,
                 const spu::ShapeView& target, const spu::Pose& pose, SweepHit& hit,
                 double tolerance = kSweepTolerance);

}  // namespace cellphys::ppe
