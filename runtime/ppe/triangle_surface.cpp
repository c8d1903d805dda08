#include "runtime/ppe/triangle_surface.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <string>
#include <utility>

#include "runtime/base/vec3.h"
#include "runtime/ppe/outward_rounding.h"
#include "runtime/ppe/shapes.h"

namespace cellphys::ppe {

namespace {

constexpr double kPi = 3.14159265358979323846;

std::string at(const char* kind, const char* what, long i) { return std::string(kind) + ": " + what + " " + std::to_string(i); }

Vec3d vertex(const std::vector<float>& v, int32_t i) { return Vec3d::load(&v[3 * size_t(i)]); }

// Edge k of triangle t as (low vertex, high vertex), a key for finding the triangle across it.
uint64_t edge_key(int32_t a, int32_t b) { return uint64_t(uint32_t(std::min(a, b))) << 32 | uint32_t(std::max(a, b)); }

// Active edges: on the border, shared by more than two triangles, wound inconsistently with its
// neighbour, or a convex crease sharper than kActiveEdgeDegrees.
void mark_edges(TriangleSurface& s) {
  const size_t n = s.triangles.size() / 3;
  // every triangle's edges as (edge, triangle << 2 | k), sorted: an edge's sides are one run
  std::vector<std::pair<uint64_t, uint32_t>> sides;
  sides.reserve(3 * n);
  for (size_t t = 0; t < n; ++t)
    for (uint32_t k = 0; k < 3; ++k)
      sides.emplace_back(edge_key(s.triangles[3 * t + k], s.triangles[3 * t + (k + 1) % 3]), uint32_t(t) << 2 | k);
  std::sort(sides.begin(), sides.end());
  const double flat = std::cos(kActiveEdgeDegrees * kPi / 180.0);
  s.edge_flags.assign(n, 0);
  for (size_t first = 0, end; first < sides.size(); first = end) {
    for (end = first + 1; end < sides.size() && sides[end].first == sides[first].first; ++end) {
    }
    for (size_t i = first; i < end; ++i) {
      const size_t t = sides[i].second >> 2, k = sides[i].second & 3;
      const int32_t a = s.triangles[3 * t + k], b = s.triangles[3 * t + (k + 1) % 3];
      bool active = end - first != 2;
      if (!active) {
        const uint32_t other = sides[i == first ? first + 1 : first].second;
        const size_t u = other >> 2, j = other & 3;
        // a consistent neighbour runs the edge the other way: from b to a
        if (s.triangles[3 * u + j] != b || s.triangles[3 * u + (j + 1) % 3] != a) {
          active = true;
        } else {
          const Vec3d n1 = Vec3d::load(&s.normals[3 * t]), n2 = Vec3d::load(&s.normals[3 * u]);
          const Vec3d far = vertex(s.vertices, s.triangles[3 * u + (j + 2) % 3]);  // the neighbour's third vertex
          const bool convex = dot(n1, far - vertex(s.vertices, a)) < 0.0;
          active = convex && dot(n1, n2) < flat;
        }
      }
      if (active) s.edge_flags[t] |= uint8_t(1u << k);
    }
  }
}

// Node `node` of the hierarchy over triangles [first, first + count) of `order`: median split on
// the longest axis of their centroids (ties by index, so every machine builds the same tree);
// an inner node's two children are adjacent.
void build_node(TriangleSurface& s, const std::vector<Vec3d>& centroid, std::vector<int32_t>& order, int32_t node,
                int32_t first, int32_t count) {
  double lo[3] = {1e300, 1e300, 1e300}, hi[3] = {-1e300, -1e300, -1e300};
  double clo[3] = {1e300, 1e300, 1e300}, chi[3] = {-1e300, -1e300, -1e300};
  for (int32_t i = first; i < first + count; ++i) {
    const int32_t t = order[i];
    for (int c = 0; c < 3; ++c) {
      const Vec3d v = vertex(s.vertices, s.triangles[3 * size_t(t) + c]);
      for (int k = 0; k < 3; ++k) lo[k] = std::min(lo[k], v[k]), hi[k] = std::max(hi[k], v[k]);
    }
    for (int k = 0; k < 3; ++k) clo[k] = std::min(clo[k], centroid[t][k]), chi[k] = std::max(chi[k], centroid[t][k]);
  }
  for (int k = 0; k < 3; ++k) s.nodes[node].min[k] = round_down(lo[k]), s.nodes[node].max[k] = round_up(hi[k]);
  if (count <= kMeshLeafTriangles) {  // a leaf's triangles in input order
    std::sort(order.begin() + first, order.begin() + first + count);
    s.nodes[node].first = first, s.nodes[node].count = count;
    return;
  }
  int axis = 0;
  for (int k = 1; k < 3; ++k)
    if (chi[k] - clo[k] > chi[axis] - clo[axis]) axis = k;
  // The lower half by centroid (a total order: which triangles fall in each half does not depend
  // on the library; their order inside it is settled at the leaves).
  const int32_t half = count / 2, child = static_cast<int32_t>(s.nodes.size());
  std::nth_element(order.begin() + first, order.begin() + first + half, order.begin() + first + count,
                   [&](int32_t x, int32_t y) {
                     return centroid[x][axis] != centroid[y][axis] ? centroid[x][axis] < centroid[y][axis] : x < y;
                   });
  s.nodes.emplace_back();
  s.nodes.emplace_back();
  s.nodes[node].first = child, s.nodes[node].count = 0;
  build_node(s, centroid, order, child, first, half);
  build_node(s, centroid, order, child + 1, first + half, count - half);
}

}  // namespace

spu::MeshView TriangleSurface::view() const {
  spu::MeshView v;
  v.num_vertices = static_cast<int32_t>(vertices.size() / 3);
  v.vertices = vertices.data();
  v.num_triangles = static_cast<int32_t>(triangles.size() / 3);
  v.triangles = triangles.data();
  v.normals = normals.data();
  v.edge_flags = edge_flags.data();
  v.num_nodes = static_cast<int32_t>(nodes.size());
  v.nodes = nodes.data();
  return v;
}

size_t TriangleSurface::bytes() const {
  return sizeof(float) * (vertices.size() + normals.size()) + sizeof(int32_t) * triangles.size() + edge_flags.size() +
         sizeof(spu::MeshNode) * nodes.size();
}

TriangleSurface build_triangle_surface(const char* kind, const float* vertices, int num_vertices,
                                       const int32_t* triangles, int num_triangles) {
  if (num_vertices < 3 || !vertices) throw ShapeError(std::string(kind) + ": needs at least 3 vertices");
  if (num_triangles < 1 || !triangles) throw ShapeError(std::string(kind) + ": needs at least 1 triangle");
  if (num_vertices > kMaxSurfaceVertices)
    throw ShapeError(std::string(kind) + ": " + std::to_string(num_vertices) + " vertices, more than " +
                     std::to_string(kMaxSurfaceVertices));
  if (num_triangles > kMaxSurfaceTriangles)
    throw ShapeError(std::string(kind) + ": " + std::to_string(num_triangles) + " triangles, more than " +
                     std::to_string(kMaxSurfaceTriangles));
  TriangleSurface s;
  s.vertices.assign(vertices, vertices + 3 * size_t(num_vertices));
  for (int k = 0; k < 3; ++k) s.lo[k] = 1e300, s.hi[k] = -1e300;
  for (int i = 0; i < num_vertices; ++i)
    for (int k = 0; k < 3; ++k) {
      const float x = vertices[3 * i + k];
      if (!std::isfinite(x)) throw ShapeError(at(kind, "vertex", i) + " is not finite");
      s.lo[k] = std::min(s.lo[k], double(x)), s.hi[k] = std::max(s.hi[k], double(x));
    }
  const double extent = norm(Vec3d::load(s.hi) - Vec3d::load(s.lo));
  std::vector<int32_t> kept;
  std::vector<Vec3d> normal;
  for (int t = 0; t < num_triangles; ++t) {
    const int32_t* v = triangles + 3 * t;
    for (int c = 0; c < 3; ++c)
      if (v[c] < 0 || v[c] >= num_vertices)
        throw ShapeError(at(kind, "triangle", t) + ": vertex index " + std::to_string(v[c]) + " out of range (" +
                         std::to_string(num_vertices) + " vertices)");
    if (v[0] == v[1] || v[1] == v[2] || v[2] == v[0])
      throw ShapeError(at(kind, "triangle", t) + " repeats a vertex (" + std::to_string(v[0]) + ", " +
                       std::to_string(v[1]) + ", " + std::to_string(v[2]) + ")");
    const Vec3d a = vertex(s.vertices, v[0]), b = vertex(s.vertices, v[1]), c = vertex(s.vertices, v[2]);
    const Vec3d area = cross(b - a, c - a);
    const double l = norm(area);
    if (!(l > 1e-12 * extent * extent)) {  // no area: its vertices are in a line
      ++s.dropped_triangles;
      continue;
    }
    kept.push_back(t);
    normal.push_back(area * (1.0 / l));
  }
  if (kept.empty()) throw ShapeError(std::string(kind) + ": no triangle has an area");
  // the hierarchy orders the triangles; the stored arrays follow that order
  std::vector<Vec3d> centroid(kept.size());
  for (size_t i = 0; i < kept.size(); ++i) {
    const int32_t* v = triangles + 3 * kept[i];
    centroid[i] = (vertex(s.vertices, v[0]) + vertex(s.vertices, v[1]) + vertex(s.vertices, v[2])) * (1.0 / 3.0);
  }
  std::vector<int32_t> order(kept.size());
  std::iota(order.begin(), order.end(), 0);
  // build on the kept triangles in input order first (indices into `kept`)
  s.triangles.resize(3 * kept.size());
  for (size_t i = 0; i < kept.size(); ++i)
    for (int c = 0; c < 3; ++c) s.triangles[3 * i + c] = triangles[3 * kept[i] + c];
  s.nodes.reserve(2 * kept.size() / kMeshLeafTriangles + 2);
  s.nodes.emplace_back();
  build_node(s, centroid, order, 0, 0, static_cast<int32_t>(kept.size()));
  std::vector<int32_t> tris(3 * kept.size());
  s.normals.resize(3 * kept.size());
  s.input_index.resize(kept.size());
  for (size_t i = 0; i < kept.size(); ++i) {
    const int32_t t = order[i];
    for (int c = 0; c < 3; ++c) tris[3 * i + c] = s.triangles[3 * size_t(t) + c];
    s.normals[3 * i] = float(normal[t].x), s.normals[3 * i + 1] = float(normal[t].y), s.normals[3 * i + 2] = float(normal[t].z);
    s.input_index[i] = kept[t];
  }
  s.triangles = std::move(tris);
  mark_edges(s);
  return s;
}

void height_field_triangles(int rows, int columns, const float spacing[2], const float* heights,
                            std::vector<float>& vertices, std::vector<int32_t>& triangles) {
  if (rows < 2 || columns < 2)
    throw ShapeError("height_field: needs at least 2 rows and 2 columns, got " + std::to_string(rows) + " x " +
                     std::to_string(columns));
  if (int64_t(rows) * columns > kMaxSurfaceVertices || 2 * int64_t(rows - 1) * (columns - 1) > kMaxSurfaceTriangles)
    throw ShapeError("height_field: " + std::to_string(rows) + " x " + std::to_string(columns) +
                     " heights, more than the " + std::to_string(kMaxSurfaceVertices) + " a surface may have");
  for (int k = 0; k < 2; ++k)
    if (!(spacing[k] > 0.0f) || !std::isfinite(spacing[k]))
      throw ShapeError(std::string("height_field: spacing ") + (k ? "y" : "x") + " must be positive and finite");
  vertices.resize(3 * size_t(rows) * columns);
  for (int i = 0; i < rows; ++i)
    for (int j = 0; j < columns; ++j) {
      const float h = heights[size_t(i) * columns + j];
      if (!std::isfinite(h))
        throw ShapeError("height_field: height at row " + std::to_string(i) + ", column " + std::to_string(j) + " is not finite");
      float* v = &vertices[3 * (size_t(i) * columns + j)];
      v[0] = float((j - 0.5 * (columns - 1)) * spacing[0]);
      v[1] = float((i - 0.5 * (rows - 1)) * spacing[1]);
      v[2] = h;
    }
  triangles.clear();
  triangles.reserve(6 * size_t(rows - 1) * (columns - 1));
  for (int i = 0; i + 1 < rows; ++i)
    for (int j = 0; j + 1 < columns; ++j) {
      const int32_t a = i * columns + j, b = a + 1, d = a + columns, c = d + 1;
      triangles.insert(triangles.end(), {a, b, c, a, c, d});  // both counter-clockwise seen from +z
    }
}

}  // namespace cellphys::ppe
