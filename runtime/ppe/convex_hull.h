// 3-D convex hull of a point cloud (quickhull) in the narrow phase's HullView layout.
//
// Topology is decided with exact integer orientation tests on the points snapped to a 2^40
// grid over their bounding box (moves ~1e-12 of the size), so the triangulated hull is always
// a closed convex mesh whatever the input. Geometry is cleaned with one relative distance
// tolerance (1e-6 of the bounding-box diagonal plus float rounding at the cloud's distance
// from the origin): near-duplicate points are welded, near-coplanar triangles merge into
// convex polygons, and vertices within the tolerance of the hull of the others (on edges, in
// faces, shallow tents left by noise) are dropped, so the vertices are the extreme points
// (a vertex sticking out by barely the tolerance may stay when dropping it would leave a point
// outside a face by more than that).
// Deterministic: the result depends only on the input values and their order.
#pragma once
#include <cstdint>
#include <vector>

#include "runtime/ppe/shapes.h"
#include "runtime/spu/shape.h"

namespace cellphys::ppe {

/// A convex polyhedron owning its arrays in exactly the HullView layout.
struct ConvexHull {
  std::vector<float> vertices;          // 3 floats each
  std::vector<float> planes;            // 4 floats each: outward unit normal, d (n.x <= d inside)
  std::vector<int32_t> face_start;      // num_faces + 1
  std::vector<int32_t> face_vertices;   // loops, counter-clockwise seen from outside
  std::vector<int32_t> edges;           // 2 vertex indices each, every undirected edge once
  std::vector<int32_t> source;          // input index of each vertex
  double tolerance = 0.0;               // distance below which points counted as coplanar

  int32_t num_vertices() const { return static_cast<int32_t>(vertices.size() / 3); }
  int32_t num_faces() const { return static_cast<int32_t>(planes.size() / 4); }
  int32_t num_edges() const { return static_cast<int32_t>(edges.size() / 2); }
  /// Points into this object's vectors: invalidated if it is modified or moved from.
  spu::HullView view() const;
};

/// Hull of count points (3 floats each). Throws ShapeError ("hull: ...") for fewer than 4
/// or more than limits.max_points points, non-finite coordinates, a degenerate cloud
/// (all coincident, collinear or coplanar within the tolerance: the message says which), or
/// a hull with more than limits.max_vertices vertices.
ConvexHull compute_convex_hull(const float* points, int count, const HullLimits& limits = {});

/// Adds offset to every vertex (rounded to float) and recomputes the planes from them.
void translate_hull(ConvexHull& hull, const double offset[3]);

}  // namespace cellphys::ppe
