#include "runtime/ppe/step_islands.h"

#include <algorithm>
#include <cstdint>
#include <numeric>

#include "runtime/ppe/world.h"

namespace cellphys::ppe {

namespace {

// Union-find over body slots; the smallest slot of a set is its root, so the result does not
// depend on the order in which pairs are joined.
class UnionFind {
 public:
  explicit UnionFind(uint32_t n) : parent_(n) { std::iota(parent_.begin(), parent_.end(), 0u); }
  uint32_t find(uint32_t x) {
    while (parent_[x] != x) x = parent_[x] = parent_[parent_[x]];
    return x;
  }
  void unite(uint32_t x, uint32_t y) {
    x = find(x), y = find(y);
    if (x != y) parent_[std::max(x, y)] = std::min(x, y);
  }

 private:
  std::vector<uint32_t> parent_;
};

}  // namespace

void build_islands(const std::vector<WorldBody>& bodies, const std::vector<WorldForce>& forces,
                   const std::vector<WorldContact>& contacts, StepStats& st, std::vector<IslandContent>& islands) {
  StageTimer t(st.times.islands_ms);
  const uint32_t n = static_cast<uint32_t>(bodies.size());
  UnionFind sets(n);
  for (const WorldContact& c : contacts)
    if (c.b != kWorldBody && bodies[c.a].awake && bodies[c.b].awake) sets.unite(c.a, c.b);
  for (const WorldForce& f : forces)
    if (f.alive && f.b != kWorldBody && bodies[f.a].awake && bodies[f.b].awake) sets.unite(f.a, f.b);
  std::vector<int32_t> island_of(n, -1);
  size_t count = 0;  // islands so far; the entries reused keep their storage (a step with fewer frees the rest)
  for (IslandContent& isl : islands) isl.bodies.clear(), isl.contacts.clear(), isl.forces.clear();
  for (uint32_t i = 0; i < n; ++i) {
    const WorldBody& b = bodies[i];
    if (!b.alive) continue;
    ++st.bodies;
    if (b.is_static) {
      ++st.static_bodies;
      continue;
    }
    if (!b.awake) {
      ++st.sleeping_bodies;
      continue;
    }
    ++st.active_bodies;
    const uint32_t r = sets.find(i);
    if (island_of[r] < 0) {
      island_of[r] = static_cast<int32_t>(count++);
      if (count > islands.size()) islands.emplace_back();
    }
    islands[island_of[r]].bodies.push_back(i);
  }
  for (uint32_t c = 0; c < contacts.size(); ++c)
    if (bodies[contacts[c].a].awake) islands[island_of[sets.find(contacts[c].a)]].contacts.push_back(c);
  for (uint32_t f = 0; f < forces.size(); ++f)
    if (forces[f].alive && bodies[forces[f].a].awake) islands[island_of[sets.find(forces[f].a)]].forces.push_back(f);
  islands.resize(count);
  st.islands = static_cast<uint32_t>(islands.size());
  st.contacts = static_cast<uint32_t>(contacts.size());
}

}  // namespace cellphys::ppe
