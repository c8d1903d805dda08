#include "runtime/ppe/step_decouple.h"

#include <algorithm>

#include "runtime/ppe/world.h"
#include "runtime/spu/workspace.h"

namespace cellphys::ppe {

namespace {

bool fits(const PackedIsland& p, size_t capacity) {
  const spu::IslandView v = spu::view_island(const_cast<unsigned char*>(p.image.data()));
  return spu::footprint(spu::counts_of(v)).total <= capacity;
}

void split(const PackContext& pc, IslandContent isl, std::vector<IslandContent>& out, uint32_t& cut) {
  if (isl.bodies.size() <= 1 || fits(pack_island(pc, isl), pc.settings.local_store_bytes)) {
    out.push_back(std::move(isl));
    return;
  }
  // Cut across the longest extent at the median body: a plane cuts few couplings.
  float lo[3] = {1e30f, 1e30f, 1e30f}, hi[3] = {-1e30f, -1e30f, -1e30f};
  for (uint32_t id : isl.bodies)
    for (int k = 0; k < 3; ++k) {
      const float x = pc.bodies[id].state.position[k];
      lo[k] = std::min(lo[k], x), hi[k] = std::max(hi[k], x);
    }
  int axis = 0;
  for (int k = 1; k < 3; ++k)
    if (hi[k] - lo[k] > hi[axis] - lo[axis]) axis = k;
  std::vector<uint32_t> order = isl.bodies;
  std::stable_sort(order.begin(), order.end(), [&](uint32_t x, uint32_t y) {
    return pc.bodies[x].state.position[axis] < pc.bodies[y].state.position[axis];
  });
  IslandContent half[2];
  half[0].bodies.assign(order.begin(), order.begin() + order.size() / 2);
  half[1].bodies.assign(order.begin() + order.size() / 2, order.end());
  for (IslandContent& h : half) std::sort(h.bodies.begin(), h.bodies.end());
  // -1: not a body of this island (the world, or a ghost from an earlier cut)
  auto side = [&](uint32_t id) {
    if (std::binary_search(half[0].bodies.begin(), half[0].bodies.end(), id)) return 0;
    return std::binary_search(half[1].bodies.begin(), half[1].bodies.end(), id) ? 1 : -1;
  };
  // a coupling whose bodies land on both sides goes into both: each holds the other as a ghost
  auto place = [&](uint32_t a, uint32_t b, auto member, uint32_t item) {
    const int sa = side(a), sb = side(b);
    if (sa >= 0) (half[sa].*member).push_back(item);
    if (sb >= 0 && sb != sa) (half[sb].*member).push_back(item);
    if (sa >= 0 && sb >= 0 && sa != sb) ++cut;
  };
  for (uint32_t c : isl.contacts) place(pc.contacts[c].a, pc.contacts[c].b, &IslandContent::contacts, c);
  for (uint32_t f : isl.forces) place(pc.forces[f].a, pc.forces[f].b, &IslandContent::forces, f);
  split(pc, std::move(half[0]), out, cut);
  split(pc, std::move(half[1]), out, cut);
}

}  // namespace

std::vector<IslandContent> decouple(const PackContext& pc, IslandContent island, uint32_t& cut_couplings) {
  std::vector<IslandContent> parts;
  split(pc, std::move(island), parts, cut_couplings);
  return parts;
}

DecoupledIslands decouple_islands(const PackContext& pc, const std::vector<IslandContent>& islands, StepStats& st) {
  StageTimer t(st.times.decouple_ms);
  DecoupledIslands d;
  d.parts.resize(islands.size());
  for (size_t k = 0; k < islands.size(); ++k) {
    d.parts[k] = decouple(pc, islands[k], st.cut_couplings);  // a copy: the sleep stage needs the island whole
    if (d.parts[k].size() > 1) ++st.decoupled_islands;
    d.waves = std::max(d.waves, d.parts[k].size());
  }
  return d;
}

}  // namespace cellphys::ppe
