// Box–box overlap by the separating-axis test and box–plane depth by the lowest corner.
#include "bench/tool/overlap.h"

#include <algorithm>
#include <cmath>

namespace cellphys::bench {
namespace {

struct Box {
  double c[3], axis[3][3], h[3];
};

Box box_of(const scene::ShapeSpec& sh, float scale, const State& s) {
  Box b;
  for (int k = 0; k < 3; ++k) {
    b.c[k] = s.p[k];
    b.h[k] = double(scale) * sh.half_extents[k];
    const double e[3] = {double(k == 0), double(k == 1), double(k == 2)};
    quat_rotate(s.q, e, b.axis[k]);
  }
  return b;
}

double dot(const double a[3], const double b[3]) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

double radius_along(const Box& b, const double u[3]) {
  return b.h[0] * std::fabs(dot(u, b.axis[0])) + b.h[1] * std::fabs(dot(u, b.axis[1])) +
         b.h[2] * std::fabs(dot(u, b.axis[2]));
}

double box_box(const Box& a, const Box& b) {
  const double d[3] = {b.c[0] - a.c[0], b.c[1] - a.c[1], b.c[2] - a.c[2]};
  double depth = INFINITY;
  auto axis = [&](const double u[3]) {
    depth = std::min(depth, radius_along(a, u) + radius_along(b, u) - std::fabs(dot(u, d)));
  };
  for (int k = 0; k < 3; ++k) axis(a.axis[k]), axis(b.axis[k]);
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) {
      const double* p = a.axis[i];
      const double* q = b.axis[j];
      double u[3] = {p[1] * q[2] - p[2] * q[1], p[2] * q[0] - p[0] * q[2], p[0] * q[1] - p[1] * q[0]};
      const double n = std::sqrt(dot(u, u));
      if (n < 1e-6) continue;  // parallel edges: the face axes cover them
      for (double& x : u) x /= n;
      axis(u);
    }
  return depth;
}

double box_plane(const Box& b, const scene::ShapeSpec& plane) {
  double n[3] = {plane.normal[0], plane.normal[1], plane.normal[2]};
  const double len = std::sqrt(dot(n, n));
  for (double& x : n) x /= len;
  return plane.offset / len - (dot(n, b.c) - radius_along(b, n));
}

}  // namespace

Overlaps::Overlaps(const scene::SceneDesc& scene) : scene_(scene), below_(scene.bodies.size(), -1) {
  for (size_t i = 0; i < scene.bodies.size(); ++i) {
    const scene::ShapeSpec* sh = nullptr;
    for (const auto& s : scene.shapes)
      if (s.name == scene.bodies[i].shape) sh = &s;
    shape_.push_back(sh);
    if (sh->type == spu::ShapeType::box) boxes_.push_back(i);
    if (sh->type == spu::ShapeType::plane) planes_.push_back(i);
  }
  for (size_t up : boxes_) {
    if (scene.bodies[up].is_static) continue;
    const float* U = scene.bodies[up].state.position;
    double best = INFINITY;
    for (size_t lo : boxes_) {
      const float* L = scene.bodies[lo].state.position;
      if (lo != up && std::hypot(U[0] - L[0], U[1] - L[1]) < 1e-3 && L[2] < U[2] && U[2] - L[2] < best)
        best = U[2] - L[2], below_[up] = int(lo);
    }
    if (below_[up] < 0 && !planes_.empty()) below_[up] = int(planes_[0]);
  }
}

double Overlaps::depth(size_t a, size_t b, const std::vector<State>& s) const {
  const scene::ShapeSpec *A = shape_[a], *B = shape_[b];
  if (A->type == spu::ShapeType::plane) std::swap(a, b), std::swap(A, B);
  if (A->type != spu::ShapeType::box) return 0;
  const Box ba = box_of(*A, scene_.bodies[a].scale, s[a]);
  if (B->type == spu::ShapeType::plane) return box_plane(ba, *B);
  if (B->type != spu::ShapeType::box) return 0;
  return box_box(ba, box_of(*B, scene_.bodies[b].scale, s[b]));
}

double Overlaps::deepest(const std::vector<State>& s) const {
  double d = 0;
  for (size_t x = 0; x < boxes_.size(); ++x) {
    for (size_t y = x + 1; y < boxes_.size(); ++y) d = std::max(d, depth(boxes_[x], boxes_[y], s));
    for (size_t p : planes_) d = std::max(d, depth(boxes_[x], p, s));
  }
  return d;
}

}  // namespace cellphys::bench
