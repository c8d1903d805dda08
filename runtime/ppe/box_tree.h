// A dynamic bounding-box tree: boxes inserted and removed one at a time, the tree kept
// balanced by rotations (an AVL tree on node heights) and shaped by the surface area each
// insertion adds. The broad phase keeps the boxes of sleeping and static bodies in it: they do
// not move, so a step pays only for the bodies that fall asleep, wake, or are added or removed,
// and for the awake bodies' queries — not for every body of the world.
#pragma once
#include <cstdint>
#include <vector>

#include "runtime/ppe/broad_phase.h"

namespace cellphys::ppe {

class BoxTree {
 public:
  /// Adds `box` for `id`; returns its leaf (a handle for remove()).
  int32_t insert(uint32_t id, const Aabb& box);
  void remove(int32_t leaf);
  void clear();
  uint32_t size() const { return leaves_; }
  /// Height of the tree (0: a single leaf or empty), for checks.
  int32_t height() const { return root_ < 0 ? 0 : nodes_[root_].height; }

  /// Every id whose box meets `box` (closed intervals: boxes that touch meet): visit(id).
  template <class Visit>
  void overlap(const Aabb& box, Visit&& visit) const;

 private:
  struct Node {
    Aabb box;
    int32_t parent = -1, child1 = -1, child2 = -1;  // child1 < 0: a leaf
    int32_t height = 0;                             // leaf 0; -1 while free
    uint32_t id = 0;
  };
  int32_t allocate();
  void release(int32_t node);
  void fix_upwards(int32_t node);
  int32_t balance(int32_t a);
  void refresh(int32_t node);  // box and height from the children
  std::vector<Node> nodes_;
  std::vector<int32_t> free_;
  mutable std::vector<int32_t> stack_;
  int32_t root_ = -1;
  uint32_t leaves_ = 0;
};

inline bool boxes_meet(const Aabb& a, const Aabb& b) {
  for (int k = 0; k < 3; ++k)
    if (b.min[k] > a.max[k] || b.max[k] < a.min[k]) return false;
  return true;
}

template <class Visit>
void BoxTree::overlap(const Aabb& box, Visit&& visit) const {
  if (root_ < 0) return;
  stack_.clear();
  stack_.push_back(root_);
  while (!stack_.empty()) {
    const Node& n = nodes_[stack_.back()];
    stack_.pop_back();
    if (!boxes_meet(n.box, box)) continue;
    if (n.child1 < 0) {
      visit(n.id);
    } else {
      stack_.push_back(n.child1);
      stack_.push_back(n.child2);
    }
  }
}

}  // namespace cellphys::ppe
