// Level geometry's storage: a triangle surface (a mesh, or a height field's grid made into
// triangles) checked, given its front normals and active edges, and ordered into a bounding
// volume hierarchy, so that the narrow phase and the queries visit only the triangles near a
// body. The shape dictionary owns one per mesh or height-field shape; spu::MeshView looks into it.
#pragma once
#include <cstdint>
#include <vector>

#include "runtime/spu/shape.h"

namespace cellphys::ppe {

/// A crease between two triangles is active (contacts on it keep their own normal) when it is
/// convex by more than this angle; flatter or hollow creases take the triangles' face normals.
inline constexpr double kActiveEdgeDegrees = 5.0;
/// Triangles per leaf of the hierarchy, at most.
inline constexpr int kMeshLeafTriangles = 4;
/// Bounds on a surface's size (the hierarchy and the indices are 32-bit).
inline constexpr int kMaxSurfaceTriangles = 1 << 22;
inline constexpr int kMaxSurfaceVertices = 1 << 22;

struct TriangleSurface {
  std::vector<float> vertices;        // 3 floats each
  std::vector<int32_t> triangles;     // 3 indices each, in leaf order
  std::vector<float> normals;         // 3 floats each
  std::vector<uint8_t> edge_flags;    // per triangle: bit k, edge k is active
  std::vector<spu::MeshNode> nodes;   // node 0 the root
  std::vector<int32_t> input_index;   // per stored triangle: its index in the input
  int32_t dropped_triangles = 0;      // input triangles with no area, left out
  double lo[3] = {}, hi[3] = {};      // the vertices' box
  spu::MeshView view() const;
  size_t bytes() const;
};

/// Checks the input and builds the surface. Throws ShapeError naming `kind` ("mesh" or
/// "height_field") and the offending vertex or triangle: a vertex not finite, an index out of
/// range, a triangle repeating a vertex, no triangle with an area, too many of either.
/// Triangles with no area (their vertices in a line, as modelling tools leave) are left out and
/// counted in dropped_triangles.
TriangleSurface build_triangle_surface(const char* kind, const float* vertices, int num_vertices,
                                       const int32_t* triangles, int num_triangles);

/// A height field's grid as vertices and triangles: `rows` x `columns` heights (row-major, row i
/// along y, column j along x), spaced spacing[0] along x and spacing[1] along y, centred on the
/// body origin, heights along body z; each cell is two triangles facing +z. Throws ShapeError for
/// fewer than 2 rows or columns, a spacing that is not positive and finite, a height that is
/// not finite, or a grid over the bounds.
void height_field_triangles(int rows, int columns, const float spacing[2], const float* heights,
                            std::vector<float>& vertices, std::vector<int32_t>& triangles);

}  // namespace cellphys::ppe
