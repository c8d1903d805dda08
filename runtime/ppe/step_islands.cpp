#include "runtime/ppe/step_islands.h"

#include <algorithm>
#include <cstdint>

#include "runtime/ppe/world.h"

namespace cellphys::ppe {

namespace {

// Union-find over the awake bodies' slots (the scratch's arrays, set for them alone); the
// smallest slot of a set is its root, so the result does not depend on the order in which
// pairs are joined.
struct UnionFind {
  std::vector<uint32_t>& parent;
  uint32_t find(uint32_t x) {
    while (parent[x] != x) x = parent[x] = parent[parent[x]];
    return x;
  }
  void unite(uint32_t x, uint32_t y) {
    x = find(x), y = find(y);
    if (x != y) parent[std::max(x, y)] = std::min(x, y);
  }
};

}  // namespace

void build_islands(const std::vector<WorldBody>& bodies, const std::vector<WorldForce>& forces,
                   const std::vector<WorldContact>& contacts, const AwakeBodies& awake, IslandScratch& scratch,
                   StepStats& st, std::vector<IslandContent>& islands) {
  StageTimer t(st, &StageTimes::islands_ms);
  const uint32_t n = static_cast<uint32_t>(bodies.size());
  scratch.parent.resize(n);
  scratch.island_of.resize(n);
  for (uint32_t i : awake.ids()) scratch.parent[i] = i, scratch.island_of[i] = -1;
  UnionFind sets{scratch.parent};
  for (const WorldContact& c : contacts)
    if (c.b != kWorldBody && bodies[c.a].awake && bodies[c.b].awake) sets.unite(c.a, c.b);
  for (const WorldForce& f : forces)
    if (f.alive && f.b != kWorldBody && bodies[f.a].awake && bodies[f.b].awake) sets.unite(f.a, f.b);
  std::vector<int32_t>& island_of = scratch.island_of;
  size_t count = 0;  // islands so far; the entries reused keep their storage (a step with fewer frees the rest)
  for (IslandContent& isl : islands) isl.bodies.clear(), isl.contacts.clear(), isl.forces.clear();
  st.bodies += awake.live();
  st.static_bodies += awake.statics();
  st.active_bodies += static_cast<uint32_t>(awake.ids().size());
  st.sleeping_bodies += awake.live() - awake.statics() - static_cast<uint32_t>(awake.ids().size());
  for (uint32_t i : awake.ids()) {
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
