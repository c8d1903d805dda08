// Narrow phase: contact points between two convex shapes, or a convex shape and the triangles
// of a mesh or height field near it (the reference design's "narrow-phase jobs on packed shape
// data"). Pure functions of shape views and poses: no state, no allocation,
// scratch on the stack within fixed bounds (about 100 KB for two hulls at the bounds below),
// ties broken by index, never by address, so the same inputs give the same bits.
//
// Conventions (see shape.h for the shapes themselves):
// - The normal points from a to b: b is pushed along +normal, a along -normal.
// - A point is world-space, midway between the two surfaces along the normal: a's surface
//   point is point + normal * penetration / 2, b's is point - normal * penetration / 2.
// - penetration > 0 is overlap. Points with penetration > -margin are reported (a speculative
//   gap, so a contact can start within a step); margin = 0 gives overlapping points only.
// - pose.scale multiplies the geometry: radius, half_height, half_extents, hull vertices and
//   hull plane offsets, and plane offsets. A plane is static and world-frame: the position and
//   orientation of its pose are ignored (only the scale applies to its offset).
// - collide(b, a) returns the same contacts as collide(a, b), in the same order, with the
//   normals negated (bit for bit): either order is computed as one canonical order.
#pragma once
#include <cstdint>

#include "runtime/spu/shape.h"

namespace cellphys::spu {

// Bounds on a hull the narrow phase accepts: its scratch copies of a hull live on the stack,
// as they would in a local store. The shape dictionary's default HullLimits (256 vertices)
// fit; a triangulated hull of V vertices has at most 2V-4 faces and 3V-6 edges.
inline constexpr int kMaxHullVertices = 256;
inline constexpr int kMaxHullFaces = 2 * kMaxHullVertices - 4;
inline constexpr int kMaxHullEdges = 3 * kMaxHullVertices - 6;
inline constexpr int kMaxHullLoopLength = 2 * kMaxHullEdges;  // sum of all face loop sizes

/// Whether a hull is well-formed and within the bounds above: indices in range, every face
/// loop of >= 3 vertices, every listed edge bordered by one face in each direction and every
/// loop edge listed (a closed mesh, V - E + F = 2), unit plane normals, vertices on their face
/// planes and no vertex outside any plane (relative tolerance 1e-4 of the hull's extent).
/// collide() trusts its hulls; the shape dictionary or a test should call this once per hull.
bool hull_supported(const HullView& hull);

/// Contact points between a and b (0..kMaxManifoldPoints), written to out. Any pair of types
/// (two static shapes, planes and triangle surfaces, give 0). A hull failing the size bounds
/// above gives 0. Against a triangle surface (one-sided, inactive edges taking the face's
/// normal: spu::MeshView) the points of every triangle the other shape's box reaches are
/// reduced to one manifold.
int collide(const ShapeView& a, const Pose& pa, const ShapeView& b, const Pose& pb, float margin,
            ContactPoint out[kMaxManifoldPoints]);

/// A pair of bodies for collide_batch: indices into the per-body shape and pose arrays.
struct NarrowPair {
  int32_t a, b;
};

/// collide() over a batch of pairs, appending contacts to out and, for each contact, the index
/// of its pair to pair_of_contact (may be null). Returns the number of contacts written.
/// A pair's manifold is never split: the batch stops at the first pair whose contacts do not
/// fit in capacity (capacity >= kMaxManifoldPoints * num_pairs always suffices).
int collide_batch(const ShapeView* shapes_by_body, const Pose* poses, const NarrowPair* pairs,
                  int num_pairs, float margin, ContactPoint* out, int32_t* pair_of_contact,
                  int capacity);

}  // namespace cellphys::spu
