#include "runtime/ppe/box_tree.h"

#include <algorithm>

namespace cellphys::ppe {

namespace {

Aabb merged(const Aabb& a, const Aabb& b) {
  Aabb m;
  for (int k = 0; k < 3; ++k) m.min[k] = std::min(a.min[k], b.min[k]), m.max[k] = std::max(a.max[k], b.max[k]);
  return m;
}

double area(const Aabb& a) {
  const double x = double(a.max[0]) - a.min[0], y = double(a.max[1]) - a.min[1], z = double(a.max[2]) - a.min[2];
  return 2.0 * (x * y + y * z + z * x);
}

}  // namespace

int32_t BoxTree::allocate() {
  if (!free_.empty()) {
    const int32_t i = free_.back();
    free_.pop_back();
    nodes_[i] = Node{};
    return i;
  }
  nodes_.emplace_back();
  return static_cast<int32_t>(nodes_.size() - 1);
}

void BoxTree::release(int32_t node) {
  nodes_[node].height = -1;
  free_.push_back(node);
}

void BoxTree::clear() {
  nodes_.clear();
  free_.clear();
  root_ = -1;
  leaves_ = 0;
}

void BoxTree::refresh(int32_t node) {
  Node& n = nodes_[node];
  n.box = merged(nodes_[n.child1].box, nodes_[n.child2].box);
  n.height = 1 + std::max(nodes_[n.child1].height, nodes_[n.child2].height);
}

int32_t BoxTree::insert(uint32_t id, const Aabb& box) {
  const int32_t leaf = allocate();
  nodes_[leaf].box = box;
  nodes_[leaf].id = id;
  ++leaves_;
  if (root_ < 0) {
    root_ = leaf;
    return leaf;
  }
  // Down to the sibling whose pairing adds the least area: making a new parent here costs the
  // merged box, and every ancestor grows by what the box adds to it (inherited).
  int32_t at = root_;
  while (nodes_[at].child1 >= 0) {
    const Node& n = nodes_[at];
    const double here = area(n.box), joined = area(merged(n.box, box));
    const double cost = 2.0 * joined, inherited = 2.0 * (joined - here);
    auto descend = [&](int32_t c) {
      const Node& child = nodes_[c];
      const double grown = area(merged(box, child.box));
      return (child.child1 < 0 ? grown : grown - area(child.box)) + inherited;
    };
    const double c1 = descend(n.child1), c2 = descend(n.child2);
    if (cost < c1 && cost < c2) break;
    at = c1 <= c2 ? n.child1 : n.child2;
  }
  const int32_t sibling = at, old_parent = nodes_[sibling].parent;
  const int32_t parent = allocate();
  Node& p = nodes_[parent];
  p.parent = old_parent;
  p.child1 = sibling;
  p.child2 = leaf;
  nodes_[sibling].parent = parent;
  nodes_[leaf].parent = parent;
  refresh(parent);
  if (old_parent < 0) root_ = parent;
  else if (nodes_[old_parent].child1 == sibling) nodes_[old_parent].child1 = parent;
  else nodes_[old_parent].child2 = parent;
  fix_upwards(parent);
  return leaf;
}

void BoxTree::remove(int32_t leaf) {
  --leaves_;
  if (leaf == root_) {
    root_ = -1;
    release(leaf);
    return;
  }
  const int32_t parent = nodes_[leaf].parent, grand = nodes_[parent].parent;
  const int32_t sibling = nodes_[parent].child1 == leaf ? nodes_[parent].child2 : nodes_[parent].child1;
  nodes_[sibling].parent = grand;
  if (grand < 0) {
    root_ = sibling;
  } else {
    if (nodes_[grand].child1 == parent) nodes_[grand].child1 = sibling;
    else nodes_[grand].child2 = sibling;
  }
  release(parent);
  release(leaf);
  fix_upwards(grand);
}

void BoxTree::fix_upwards(int32_t node) {
  while (node >= 0) {
    node = balance(node);
    refresh(node);
    node = nodes_[node].parent;
  }
}

// Rotates the taller child of `a` up when the two children's heights differ by more than one;
// returns the node now at a's place.
int32_t BoxTree::balance(int32_t a) {
  if (nodes_[a].child1 < 0 || nodes_[a].height < 2) return a;
  const int32_t b = nodes_[a].child1, c = nodes_[a].child2;
  const int32_t lean = nodes_[c].height - nodes_[b].height;
  if (lean >= -1 && lean <= 1) return a;
  // up: the taller child; its taller child stays under it, its shorter one moves under a
  const int32_t up = lean > 1 ? c : b;
  const int32_t f = nodes_[up].child1, g = nodes_[up].child2;
  const int32_t keep = nodes_[f].height > nodes_[g].height ? f : g, give = keep == f ? g : f;
  const int32_t above = nodes_[a].parent;
  nodes_[up].parent = above;
  nodes_[a].parent = up;
  if (above < 0) root_ = up;
  else if (nodes_[above].child1 == a) nodes_[above].child1 = up;
  else nodes_[above].child2 = up;
  nodes_[up].child1 = a;
  nodes_[up].child2 = keep;
  if (up == c) nodes_[a].child2 = give;
  else nodes_[a].child1 = give;
  nodes_[give].parent = a;
  refresh(a);
  refresh(up);
  return up;
}

}  // namespace cellphys::ppe
