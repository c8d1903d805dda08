#include "runtime/ppe/query_tree.h"

#include <cstring>
#include <limits>

namespace cellphys::ppe {

namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();

void empty(float (&min)[3], float (&max)[3]) {
  for (int k = 0; k < 3; ++k) min[k] = kInf, max[k] = -kInf;
}
void grow(float (&min)[3], float (&max)[3], const float* bmin, const float* bmax) {
  for (int k = 0; k < 3; ++k) min[k] = std::min(min[k], bmin[k]), max[k] = std::max(max[k], bmax[k]);
}
double area_of(const float* min, const float* max) {
  const double x = double(max[0]) - min[0], y = double(max[1]) - min[1], z = double(max[2]) - min[2];
  return 2.0 * (x * y + y * z + z * x);
}

}  // namespace

void QueryTree::build(const std::vector<Aabb>& boxes, const std::vector<uint32_t>& ids) {
  items_ = ids;
  nodes_.clear();
  if (items_.empty()) return;
  nodes_.reserve(2 * (items_.size() / kLeafSize + 1));
  struct Range {
    uint32_t node, begin, end;
  };
  std::vector<Range> todo;
  nodes_.push_back({});
  todo.push_back({0, 0, uint32_t(items_.size())});
  auto centre = [&](uint32_t id, int k) { return double(boxes[id].min[k]) + boxes[id].max[k]; };
  while (!todo.empty()) {
    const Range r = todo.back();
    todo.pop_back();
    Node n;
    empty(n.min, n.max);
    double lo[3] = {kInf, kInf, kInf}, hi[3] = {-kInf, -kInf, -kInf};
    for (uint32_t i = r.begin; i < r.end; ++i) {
      const Aabb& b = boxes[items_[i]];
      grow(n.min, n.max, b.min, b.max);
      for (int k = 0; k < 3; ++k) lo[k] = std::min(lo[k], centre(items_[i], k)), hi[k] = std::max(hi[k], centre(items_[i], k));
    }
    if (r.end - r.begin <= kLeafSize) {
      n.first = r.begin, n.count = r.end - r.begin;
      nodes_[r.node] = n;
      continue;
    }
    // Median split along the longest spread of the centres (ties by id: the same tree for
    // the same world).
    int axis = 0;
    for (int k = 1; k < 3; ++k)
      if (hi[k] - lo[k] > hi[axis] - lo[axis]) axis = k;
    const uint32_t mid = r.begin + (r.end - r.begin) / 2;
    std::nth_element(items_.begin() + r.begin, items_.begin() + mid, items_.begin() + r.end,
                     [&](uint32_t a, uint32_t b) {
                       const double ca = centre(a, axis), cb = centre(b, axis);
                       return ca < cb || (ca == cb && a < b);
                     });
    n.first = uint32_t(nodes_.size()), n.count = 0;
    nodes_[r.node] = n;
    nodes_.push_back({});
    nodes_.push_back({});
    todo.push_back({n.first + 1, mid, r.end});
    todo.push_back({n.first, r.begin, mid});
  }
}

void QueryTree::refit(const std::vector<Aabb>& boxes) {
  // Children come after their parent: one backward pass sees every child before its parent.
  for (size_t i = nodes_.size(); i-- > 0;) {
    Node& n = nodes_[i];
    empty(n.min, n.max);
    if (n.count > 0) {
      for (uint32_t k = n.first; k < n.first + n.count; ++k) grow(n.min, n.max, boxes[items_[k]].min, boxes[items_[k]].max);
    } else {
      for (uint32_t c = n.first; c < n.first + 2; ++c) grow(n.min, n.max, nodes_[c].min, nodes_[c].max);
    }
  }
}

double QueryTree::area() const {
  double a = 0.0;
  for (const Node& n : nodes_) a += area_of(n.min, n.max);
  return a;
}

bool QueryIndex::Key::operator==(const Key& k) const { return std::memcmp(this, &k, sizeof(Key)) == 0; }

void QueryIndex::update(const std::vector<WorldBody>& bodies, const ShapeDictionary& shapes, uint64_t revision) {
  if (built_.load(std::memory_order_acquire) == revision) return;
  std::lock_guard<std::mutex> guard(lock_);
  if (built_.load(std::memory_order_relaxed) == revision) return;
  const size_t n = bodies.size();
  bool same_bodies = boxes_.size() == n;
  boxes_.resize(n);
  keys_.resize(n);
  std::vector<uint32_t> ids, planes;
  for (uint32_t i = 0; i < n; ++i) {
    const WorldBody& b = bodies[i];
    if (!b.alive) continue;
    if (shapes.type(b.shape) == spu::ShapeType::plane) {
      planes.push_back(i);
      continue;
    }
    ids.push_back(i);
    Key k;
    std::memset(&k, 0, sizeof k);  // the padding too: keys compare by bytes
    std::copy(b.state.position, b.state.position + 3, k.position);
    std::copy(b.state.orientation, b.state.orientation + 4, k.orientation);
    k.scale = b.scale, k.shape = b.shape;
    if (k == keys_[i] && built_.load(std::memory_order_relaxed) != ~uint64_t(0)) continue;
    keys_[i] = k;
    shapes.world_aabb(b.shape, pose_of(b), boxes_[i].min, boxes_[i].max);
  }
  same_bodies = same_bodies && ids == ids_;
  planes_ = std::move(planes);
  if (same_bodies) tree_.refit(boxes_);
  if (!same_bodies || tree_.area() > kRebuildGrowth * built_area_) {
    ids_ = std::move(ids);
    tree_.build(boxes_, ids_);
    built_area_ = tree_.area();
  }
  built_.store(revision, std::memory_order_release);
}

}  // namespace cellphys::ppe
