// Walking a triangle surface's bounding volume hierarchy (spu::MeshView): the triangles whose
// leaves a box or a ray reaches, in the hierarchy's fixed order (first child first), so the
// same query visits the same triangles in the same order everywhere.
#pragma once
#include <cstdint>

#include "runtime/spu/shape.h"

namespace cellphys::spu {

/// Deep enough for any hierarchy the shape dictionary builds (median splits: depth ~ log2 n).
inline constexpr int kSurfaceTreeStack = 64;

/// Calls visit(triangle) for every triangle of a leaf whose box overlaps [lo, hi] (body
/// coordinates, unit scale). `visit` returns false to stop the walk.
template <class Visit>
void visit_triangles_in_box(const MeshView& m, const double lo[3], const double hi[3], Visit&& visit) {
  if (m.num_nodes <= 0) return;
  int32_t stack[kSurfaceTreeStack];
  int top = 0;
  stack[top++] = 0;
  while (top > 0) {
    const MeshNode& nd = m.nodes[stack[--top]];
    if (nd.min[0] > hi[0] || nd.max[0] < lo[0] || nd.min[1] > hi[1] || nd.max[1] < lo[1] || nd.min[2] > hi[2] ||
        nd.max[2] < lo[2])
      continue;
    if (nd.count > 0) {
      for (int32_t t = nd.first; t < nd.first + nd.count; ++t)
        if (!visit(t)) return;
      continue;
    }
    if (top + 2 > kSurfaceTreeStack) continue;  // deeper than any tree the dictionary builds
    stack[top++] = nd.first + 1;  // popped second
    stack[top++] = nd.first;
  }
}

/// The same for the segment origin + t dir, t in [0, max_t] (body coordinates): every leaf the
/// segment's slab test does not rule out.
template <class Visit>
void visit_triangles_on_ray(const MeshView& m, const double origin[3], const double dir[3], double max_t, Visit&& visit) {
  if (m.num_nodes <= 0) return;
  double inv[3];
  for (int k = 0; k < 3; ++k) inv[k] = 1.0 / dir[k];  // +-inf for an axis the ray runs across
  int32_t stack[kSurfaceTreeStack];
  int top = 0;
  stack[top++] = 0;
  while (top > 0) {
    const MeshNode& nd = m.nodes[stack[--top]];
    double t0 = 0.0, t1 = max_t;
    bool miss = false;
    for (int k = 0; k < 3 && !miss; ++k) {
      if (dir[k] == 0.0) {
        miss = origin[k] < nd.min[k] || origin[k] > nd.max[k];
        continue;
      }
      double a = (nd.min[k] - origin[k]) * inv[k], b = (nd.max[k] - origin[k]) * inv[k];
      if (a > b) {
        const double x = a;
        a = b, b = x;
      }
      t0 = a > t0 ? a : t0;
      t1 = b < t1 ? b : t1;
      miss = t0 > t1;
    }
    if (miss) continue;
    if (nd.count > 0) {
      for (int32_t t = nd.first; t < nd.first + nd.count; ++t)
        if (!visit(t)) return;
      continue;
    }
    if (top + 2 > kSurfaceTreeStack) continue;
    stack[top++] = nd.first + 1;
    stack[top++] = nd.first;
  }
}

}  // namespace cellphys::spu
