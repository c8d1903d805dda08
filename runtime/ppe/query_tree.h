// A bounding-volume tree over the bodies' world boxes, for the world's queries between steps
// (runtime/ppe/world_queries.cpp). Built top down by median splits along the longest axis of
// the box centres (at most kLeafSize boxes a leaf), laid out parent before children so a refit
// is one backward pass. The world's index (QueryIndex) keeps it current: a body added or
// removed rebuilds it; bodies moved refit it, and rebuild it once the refit tree's total node
// area has grown past kRebuildGrowth times what the build had (moved bodies make loose nodes).
// Planes are unbounded and kept apart, in a list every query reads.
#pragma once
#include <algorithm>
#include <atomic>
#include <cstdint>
#include <mutex>
#include <vector>

#include "runtime/base/vec3.h"
#include "runtime/ppe/body_records.h"
#include "runtime/ppe/broad_phase.h"
#include "runtime/ppe/shapes.h"

namespace cellphys::ppe {

class QueryTree {
 public:
  static constexpr uint32_t kLeafSize = 4;

  /// A tree over boxes[id] for each id in ids.
  void build(const std::vector<Aabb>& boxes, const std::vector<uint32_t>& ids);
  /// The same tree over new boxes for the same ids.
  void refit(const std::vector<Aabb>& boxes);
  size_t size() const { return items_.size(); }
  size_t nodes() const { return nodes_.size(); }
  /// Sum of the surface areas of all nodes: what a query pays, roughly.
  double area() const;

  /// The ids whose boxes, grown by `grow` on each side, the ray origin + t dir meets for some
  /// t in [0, max_t], nearest box first: visit(id, max_t) may shorten max_t (a hit found).
  template <class Visit>
  void ray(const Vec3d& origin, const Vec3d& dir, double max_t, const Vec3d& grow, Visit&& visit) const;
  /// The ids whose boxes meet `box`: visit(id).
  template <class Visit>
  void overlap(const Aabb& box, Visit&& visit) const;

 private:
  struct Node {
    float min[3], max[3];
    uint32_t first;  // internal: the left child (the right one follows); leaf: first item
    uint32_t count;  // 0 for an internal node
  };
  // Entry t of the ray into a node's grown box, or false.
  static bool enter(const Node& n, const Vec3d& o, const Vec3d& inv, const bool (&flat)[3], const Vec3d& grow,
                    double max_t, double& t);
  std::vector<Node> nodes_;
  std::vector<uint32_t> items_;  // ids, grouped by leaf
};

/// The world's tree, kept current against its bodies. Queries of one world may run on
/// several threads at once: the first to find the tree stale brings it up to date under a lock.
class QueryIndex {
 public:
  static constexpr double kRebuildGrowth = 1.5;

  /// Up to date for `revision` (the world's count of changes to its bodies: added, removed,
  /// moved); only the bodies whose pose or shape changed get new boxes.
  void update(const std::vector<WorldBody>& bodies, const ShapeDictionary& shapes, uint64_t revision);
  const QueryTree& tree() const { return tree_; }
  const std::vector<uint32_t>& planes() const { return planes_; }

 private:
  struct Key {  // what a body's box is made of
    float position[3], orientation[4], scale;
    uint32_t shape;
    bool operator==(const Key& k) const;
  };
  std::mutex lock_;
  std::atomic<uint64_t> built_{~uint64_t(0)};
  QueryTree tree_;
  std::vector<Aabb> boxes_;  // per body slot
  std::vector<Key> keys_;    // per body slot
  std::vector<uint32_t> ids_, planes_;
  double built_area_ = 0.0;
};

// ---- traversal ---------------------------------------------------------------------------------

inline bool QueryTree::enter(const Node& n, const Vec3d& o, const Vec3d& inv, const bool (&flat)[3],
                             const Vec3d& grow, double max_t, double& t) {
  double lo = 0.0, hi = max_t;
  for (int k = 0; k < 3; ++k) {
    const double a = double(n.min[k]) - grow[k], b = double(n.max[k]) + grow[k];
    if (flat[k]) {  // the ray runs along the slab: inside it or never
      if (o[k] < a || o[k] > b) return false;
      continue;
    }
    double t0 = (a - o[k]) * inv[k], t1 = (b - o[k]) * inv[k];
    if (t0 > t1) std::swap(t0, t1);
    lo = std::max(lo, t0);
    hi = std::min(hi, t1);
    if (lo > hi) return false;
  }
  t = lo;
  return true;
}

template <class Visit>
void QueryTree::ray(const Vec3d& origin, const Vec3d& dir, double max_t, const Vec3d& grow, Visit&& visit) const {
  if (nodes_.empty()) return;
  const bool flat[3] = {dir.x == 0.0, dir.y == 0.0, dir.z == 0.0};
  const Vec3d inv = {flat[0] ? 0.0 : 1.0 / dir.x, flat[1] ? 0.0 : 1.0 / dir.y, flat[2] ? 0.0 : 1.0 / dir.z};
  struct Entry {
    uint32_t node;
    double t;
  };
  Entry stack[128];
  int top = 0;
  double t;
  if (!enter(nodes_[0], origin, inv, flat, grow, max_t, t)) return;
  stack[top++] = {0, t};
  while (top > 0) {
    const Entry e = stack[--top];
    if (e.t > max_t) continue;
    const Node& n = nodes_[e.node];
    if (n.count > 0) {
      for (uint32_t i = n.first; i < n.first + n.count; ++i) visit(items_[i], max_t);
      continue;
    }
    double tl, tr;
    const bool l = enter(nodes_[n.first], origin, inv, flat, grow, max_t, tl);
    const bool r = enter(nodes_[n.first + 1], origin, inv, flat, grow, max_t, tr);
    // Push the far child first so the near one is visited first.
    if (l && r) {
      const bool left_first = tl <= tr;
      stack[top++] = left_first ? Entry{n.first + 1, tr} : Entry{n.first, tl};
      stack[top++] = left_first ? Entry{n.first, tl} : Entry{n.first + 1, tr};
    } else if (l) {
      stack[top++] = {n.first, tl};
    } else if (r) {
      stack[top++] = {n.first + 1, tr};
    }
  }
}

template <class Visit>
void QueryTree::overlap(const Aabb& box, Visit&& visit) const {
  if (nodes_.empty()) return;
  uint32_t stack[128];
  int top = 0;
  stack[top++] = 0;
  while (top > 0) {
    const Node& n = nodes_[stack[--top]];
    bool meets = true;
    for (int k = 0; k < 3; ++k) meets = meets && !(n.max[k] < box.min[k] || n.min[k] > box.max[k]);
    if (!meets) continue;
    if (n.count > 0) {
      for (uint32_t i = n.first; i < n.first + n.count; ++i) visit(items_[i]);
      continue;
    }
    stack[top++] = n.first + 1;
    stack[top++] = n.first;
  }
}

}  // namespace cellphys::ppe
