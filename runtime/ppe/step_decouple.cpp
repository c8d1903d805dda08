#include "runtime/ppe/step_decouple.h"

#include <algorithm>
#include <cassert>
#include <cstring>

#include "runtime/ppe/world.h"
#include "runtime/spu/island_image.h"
#include "runtime/spu/workspace.h"

namespace cellphys::ppe {

namespace {

// Whether an island surely fits, from its content alone: counts at least those its image would
// have (every coupling end outside the island a ghost, every body a damping and a gyroscopic
// instance, every section its alignment, every coupling two blocks, every scratch the largest
// kernel's). The footprint grows with each count, so an island under this bound needs no
// packing to know it fits; one over it is packed and measured.
// (`exact`: the ghosts counted one by one; otherwise every coupling end is taken for one, which
// bounds the count from above at no cost.)
bool surely_fits(const PackContext& pc, const IslandContent& isl, size_t fit, bool exact) {
  const auto inside = [&](uint32_t id) {
    return id == kWorldBody || std::binary_search(isl.bodies.begin(), isl.bodies.end(), id);
  };
  const size_t couplings = isl.contacts.size() + isl.forces.size();
  size_t ghosts = exact ? 0 : 2 * couplings, force_bytes = 0;
  for (uint32_t c : isl.contacts)
    if (exact) ghosts += !inside(pc.contacts[c].a) + !inside(pc.contacts[c].b);
  for (uint32_t f : isl.forces) {
    if (exact) ghosts += !inside(pc.forces[f].a) + !inside(pc.forces[f].b);
    force_bytes += pc.forces[f].instance.size();
  }
  const size_t n = isl.bodies.size() + ghosts;
  if (n > (1u << 20)) return false;
  return spu::footprint(counts_at_least(pc.settings, n, isl.contacts.size(), force_bytes, couplings)).total <= fit;
}

bool fits(const PackContext& pc, const IslandContent& isl, size_t fit, PackScratch& scratch, PackedIsland& probe) {
  if (isl.bodies.size() <= 1 || surely_fits(pc, isl, fit, false) || surely_fits(pc, isl, fit, true)) return true;
  pack_island(pc, isl, scratch, probe);
  const spu::IslandView v = spu::view_island(probe.image.data());
  return spu::footprint(spu::counts_of(v)).total <= fit;
}

// A float's order as an unsigned integer's (zeros as one: `<` holds them equal).
uint32_t ordered(float x) {
  if (x == 0.0f) x = 0.0f;
  uint32_t u;
  std::memcpy(&u, &x, sizeof u);
  return (u & 0x80000000u) ? ~u : (u | 0x80000000u);
}

// `from` copied into `to`, whose storage is kept from earlier steps.
void copy_content(const IslandContent& from, IslandContent& to) {
  to.bodies.assign(from.bodies.begin(), from.bodies.end());
  to.contacts.assign(from.contacts.begin(), from.contacts.end());
  to.forces.assign(from.forces.begin(), from.forces.end());
}

struct Cutting {
  const PackContext& pc;
  PackScratch& scratch;
  PackedIsland& probe;
  CutScratch& cuts;
  std::vector<IslandContent>& out;
  size_t used = 0;
  uint32_t& cut;

  // `isl` into parts that fit the local store, appended to `out`: whole when it fits, else cut
  // in two (the halves kept at `depth` of cuts.halves) and each half so. `too_big`: the caller
  // found it does not fit already.
  void split(const IslandContent& isl, size_t depth, bool too_big = false) {
    if (!too_big && fits(pc, isl, pc.settings.local_store_bytes, scratch, probe)) {
      if (used == out.size()) out.emplace_back();
      copy_content(isl, out[used++]);
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
    // the bodies along the axis, equal positions in island order (a stable sort without the
    // heap buffer std::stable_sort takes): (position, place) keys
    std::vector<uint64_t>& keys = cuts.keys;
    keys.resize(isl.bodies.size());
    for (size_t i = 0; i < isl.bodies.size(); ++i)
      keys[i] = uint64_t(ordered(pc.bodies[isl.bodies[i]].state.position[axis])) << 32 | i;
    std::sort(keys.begin(), keys.end());
    assert(2 * depth + 1 < cuts.halves.size());
    IslandContent* half = &cuts.halves[2 * depth];
    const size_t middle = keys.size() / 2;
    for (int h = 0; h < 2; ++h) {
      half[h].bodies.clear(), half[h].contacts.clear(), half[h].forces.clear();
      for (size_t i = h ? middle : 0; i < (h ? keys.size() : middle); ++i) half[h].bodies.push_back(isl.bodies[keys[i] & 0xffffffffu]);
      std::sort(half[h].bodies.begin(), half[h].bodies.end());
    }
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
    split(half[0], depth + 1);
    split(half[1], depth + 1);
  }
};

}  // namespace

size_t decouple(const PackContext& pc, const IslandContent& island, size_t fit, uint32_t& cut_couplings,
                PackScratch& scratch, PackedIsland& probe, CutScratch& cuts, std::vector<IslandContent>& parts) {
  if (fits(pc, island, fit, scratch, probe)) return 0;  // the island whole
  // Each cut halves the bodies: a world's 2^32 ids are cut at most 32 deep.
  if (cuts.halves.size() < 2 * CutScratch::kMaxDepth) cuts.halves.resize(2 * CutScratch::kMaxDepth);
  Cutting c{pc, scratch, probe, cuts, parts, 0, cut_couplings};
  c.split(island, 0, /*too_big=*/true);
  parts.resize(c.used);
  return c.used;
}

void decouple_islands(const PackContext& pc, const std::vector<IslandContent>& islands, size_t whole_bytes,
                      StepStats& st, PackScratch& scratch, DecoupledIslands& d) {
  StageTimer t(st, &StageTimes::decouple_ms);
  const size_t fit = std::max(pc.settings.local_store_bytes, std::min(whole_bytes, pc.settings.whole_island_bytes));
  d.islands = &islands;
  d.waves = 0;
  d.parts.resize(islands.size());
  d.used.resize(islands.size());
  for (size_t k = 0; k < islands.size(); ++k) {
    d.used[k] = decouple(pc, islands[k], fit, st.cut_couplings, scratch, d.probe, d.cuts, d.parts[k]);
    if (d.is_split(k)) ++st.decoupled_islands;
    d.waves = std::max(d.waves, d.count(k));
  }
}

}  // namespace cellphys::ppe
