#include "runtime/ppe/island_packer.h"

#include <algorithm>
#include <cstring>

#include "runtime/base/radix_sort.h"
#include "runtime/ppe/world.h"
#include "runtime/spu/workspace.h"

namespace cellphys::ppe {

using namespace cellphys::gen;

namespace {

Rigid_Body_Fields fields_of(const WorldBody& b) {
  Rigid_Body_Fields f;
  copy_state(b.state, f);
  std::copy(b.inertia, b.inertia + 6, f.inertia_body);
  std::copy(b.inverse_inertia, b.inverse_inertia + 6, f.inverse_inertia_body);
  f.mass = b.mass;
  f.inverse_mass = 1.0f / b.mass;
  f.friction = b.friction;
  f.linear_damping = b.linear_damping;
  f.angular_damping = b.angular_damping;
  f.shape_index = b.shape;
  f.scale = b.scale;
  return f;
}

bool isotropic(const float* I) { return I[0] == I[1] && I[1] == I[2] && I[3] == 0 && I[4] == 0 && I[5] == 0; }

constexpr int32_t kOutside = -2;  // as the kernel's validation calls a body that is not in the island

int32_t local_of(const std::vector<int32_t>& local, uint32_t id) { return id == kWorldBody ? -1 : local[id]; }

// Element by element: std::copy of three floats compiled to a call to memcpy, whose bytes the
// loads that follow waited for (half of pack_island's time in a world of many contacts).
void copy3(const float* from, float* to) { to[0] = from[0], to[1] = from[1], to[2] = from[2]; }

Contact_Force contact_instance(const WorldContact& c, int32_t a, int32_t b) {
  Contact_Force_Fields f;
  copy3(c.point.point, f.point);
  copy3(c.point.normal, f.normal);
  copy3(c.anchor, f.anchor);
  f.penetration = c.point.penetration;
  f.friction = c.friction;
  f.mass = c.mass;
  f.load = c.load;
  f.sticking = c.sticking;
  f.fall = c.fall;
  f.hold = c.hold;
  f.body_a = a;
  f.body_b = b;
  Contact_Force packed;
  pack(f, packed);
  return packed;
}

void set_bodies(const ForceInfo& info, std::vector<unsigned char>& inst, int32_t a, int32_t b) {
  std::memcpy(inst.data() + info.offset_body_a, &a, 4);
  if (info.offset_body_b >= 0) std::memcpy(inst.data() + info.offset_body_b, &b, 4);
}

}  // namespace

// The step's contacts come mostly in pair order already (the 5,050-box pyramid's 59,800 in two
// sorted runs), so a sorted list is left as it is and two runs are merged; otherwise a radix sort
// of (a, b, index) keys when they fit 64 bits (std::sort took 3% of the pyramid's step), else
// std::sort.
void sort_contacts_by_pair(const std::vector<WorldContact>& contacts, std::vector<uint32_t>& cs, PackScratch& scratch) {
  const auto before = [&](uint32_t x, uint32_t y) {
    const WorldContact &a = contacts[x], &b = contacts[y];
    return a.a != b.a ? a.a < b.a : a.b != b.b ? a.b < b.b : x < y;
  };
  size_t second_run = 0, descents = 0;
  for (size_t k = 1; k < cs.size() && descents < 2; ++k)
    if (before(cs[k], cs[k - 1])) ++descents, second_run = k;
  if (descents == 0) return;
  if (descents == 1) {
    std::vector<uint32_t>& merged = scratch.merged;
    merged.resize(cs.size());
    std::merge(cs.begin(), cs.begin() + ptrdiff_t(second_run), cs.begin() + ptrdiff_t(second_run), cs.end(), merged.begin(),
               before);
    cs.swap(merged);
    return;
  }
  uint32_t any_a = 0, any_b = 0, any_c = 0;
  for (uint32_t c : cs) any_a |= contacts[c].a, any_b |= contacts[c].b, any_c |= c;
  const int bits_b = bits_used(any_b), bits_c = bits_used(any_c);
  if (bits_used(any_a) + bits_b + bits_c > 64) {
    std::sort(cs.begin(), cs.end(), before);  // a total order: std::sort allocates nothing
    return;
  }
  std::vector<uint64_t>& keys = scratch.keys;
  keys.resize(cs.size());
  for (size_t k = 0; k < cs.size(); ++k) {
    const WorldContact& w = contacts[cs[k]];
    keys[k] = (uint64_t(w.a) << bits_b | w.b) << bits_c | cs[k];
  }
  radix_sort_keys(keys, scratch.key_buffer);
  const uint64_t index = (uint64_t{1} << bits_c) - 1;  // bits_c <= 32
  for (size_t k = 0; k < cs.size(); ++k) cs[k] = uint32_t(keys[k] & index);
}

void match_capacities(std::vector<PackScratch>& scratches) {
  for (PackScratch& s : scratches)
    for (const PackScratch& o : scratches) {
      if (&s == &o) continue;
      s.builder.reserve_like(o.builder);
      for (auto m : {&PackScratch::ghosts, &PackScratch::jointed, &PackScratch::contacts, &PackScratch::merged})
        (s.*m).reserve((o.*m).capacity());
      s.keys.reserve(o.keys.capacity());
      s.key_buffer.reserve(o.key_buffer.capacity());
      s.instance.reserve(o.instance.capacity());
      if (s.local.size() < o.local.size()) s.local.resize(o.local.size(), kOutside);
    }
}

void pack_island(const PackContext& pc, const IslandContent& isl, PackScratch& scratch, PackedIsland& p, bool seal) {
  const WorldSettings& s = pc.settings;
  spu::IslandBuilder& ib = scratch.builder;
  ib.reset();
  ib.set_step(s.dt);
  ib.set_integrator(s.integrator);
  ib.set_solver(static_cast<uint32_t>(s.solver));
  ib.set_tolerance(s.tolerance);
  ib.set_max_halvings(s.max_halvings);
  pack(s.globals, ib.params());
  p.bodies.clear();
  p.ghost.clear();
  p.result.clear();
  // ghosts: the bodies of other parts its contacts and forces reach (marked: the island's
  // bodies hold 0 in `local` until they get their index)
  std::vector<int32_t>& local = scratch.local;
  if (local.size() < pc.bodies.size()) local.resize(pc.bodies.size(), kOutside);
  for (uint32_t id : isl.bodies) local[id] = 0;
  std::vector<uint32_t>& ghosts = scratch.ghosts;
  ghosts.clear();
  auto reach = [&](uint32_t id) {
    if (id != kWorldBody && local[id] == kOutside) ghosts.push_back(id);
  };
  for (uint32_t c : isl.contacts) reach(pc.contacts[c].a), reach(pc.contacts[c].b);
  for (uint32_t f : isl.forces) reach(pc.forces[f].a), reach(pc.forces[f].b);
  std::sort(ghosts.begin(), ghosts.end());
  ghosts.erase(std::unique(ghosts.begin(), ghosts.end()), ghosts.end());
  // the bodies a joint holds (kBodyTurnsByKick)
  std::vector<uint32_t>& jointed = scratch.jointed;
  jointed.clear();
  for (uint32_t fi : isl.forces) {
    const WorldForce& f = pc.forces[fi];
    if (!kForceTable[static_cast<int>(f.type)].joint) continue;
    jointed.push_back(f.a);
    if (f.b != kWorldBody) jointed.push_back(f.b);
  }
  std::sort(jointed.begin(), jointed.end());
  p.bodies.resize(isl.bodies.size() + ghosts.size());
  std::merge(isl.bodies.begin(), isl.bodies.end(), ghosts.begin(), ghosts.end(), p.bodies.begin());
  for (uint32_t id : p.bodies) {
    const WorldBody& b = pc.start[id];
    const bool ghost = local[id] == kOutside;
    local[id] = static_cast<int32_t>(p.ghost.size());
    p.ghost.push_back(ghost);
    Rigid_Body_Fields f = fields_of(b);
    if (s.integrator == spu::Integrator::implicit_split && !isotropic(b.inertia) &&
        std::binary_search(jointed.begin(), jointed.end(), id))
      f.flags |= spu::kBodyTurnsByKick;
    if (ghost) {  // kinematic, from where the step started at its latest velocity
      const WorldBody& latest = pc.bodies[id];
      std::copy(latest.state.velocity, latest.state.velocity + 3, f.velocity);
      std::copy(latest.state.angular_velocity, latest.state.angular_velocity + 3, f.angular_velocity);
      f.inverse_mass = 0.0f;
      std::fill(f.inverse_inertia_body, f.inverse_inertia_body + 6, 0.0f);
    }
    const int local = ib.add_body(f);
    if (ghost) continue;
    if (b.linear_damping > 0 || b.angular_damping > 0) {
      Damping_Force_Fields d;
      d.linear = b.linear_damping;
      d.angular = b.angular_damping;
      d.body_a = local;
      Damping_Force dp;
      pack(d, dp);
      ib.add(ForceType::damping, dp);
    }
    // the default integrator rotates bodies exactly; the others need the torque as a force
    if (s.integrator != spu::Integrator::implicit_split && !isotropic(b.inertia)) {
      Gyroscopic_Force gy{};
      gy.body_a = local;
      ib.add(ForceType::gyroscopic, gy);
    }
  }
  if (s.globals.gravity[0] != 0 || s.globals.gravity[1] != 0 || s.globals.gravity[2] != 0) ib.add_global(ForceType::gravity);
  // contacts grouped by body pair, in a fixed order
  std::vector<uint32_t>& cs = scratch.contacts;
  cs.assign(isl.contacts.begin(), isl.contacts.end());
  sort_contacts_by_pair(pc.contacts, cs, scratch);
  for (uint32_t c : cs) {
    const WorldContact& wc = pc.contacts[c];
    ib.add(ForceType::contact, contact_instance(wc, local_of(local, wc.a), local_of(local, wc.b)));
  }
  for (uint32_t fid : isl.forces) {
    const WorldForce& f = pc.forces[fid];
    const ForceInfo& info = kForceTable[static_cast<int>(f.type)];
    std::vector<unsigned char>& inst = scratch.instance;
    inst.assign(f.instance.begin(), f.instance.end());
    set_bodies(info, inst, local_of(local, f.a), local_of(local, f.b));
    ib.add_force(f.type, inst.data(), inst.size());
  }
  for (uint32_t id : p.bodies) local[id] = kOutside;
  ib.finish(p.image, seal);
  p.sealed = seal;
}

spu::IslandCounts counts_at_least(const WorldSettings& s, size_t bodies, size_t contacts, size_t force_bytes,
                                  size_t couplings) {
  size_t instances = contacts * kForceTable[static_cast<int>(ForceType::contact)].instance_size + force_bytes;
  instances += bodies * (kForceTable[static_cast<int>(ForceType::damping)].instance_size +
                         kForceTable[static_cast<int>(ForceType::gyroscopic)].instance_size);
  instances += size_t{kNumForceTypes} * 16;
  spu::IslandCounts c;
  c.num_bodies = static_cast<uint32_t>(bodies);
  c.num_blocks = static_cast<uint32_t>(2 * couplings);
  c.pair_instances = static_cast<uint32_t>(couplings);
  c.image_bytes = static_cast<uint32_t>(spu::island_layout(c.num_bodies, kNumForceTypes).instances + instances);
  c.integrator = s.integrator;
  c.solver = s.solver;
  c.force_types = ~0u;
  return c;
}

void unpack_island(const PackedIsland& p, std::vector<WorldBody>& bodies) {
  const size_t n = p.bodies.size();
  const unsigned char* src = p.result.data() + p.result.size() - n * sizeof(Rigid_Body);
  for (size_t i = 0; i < n; ++i) {
    if (p.ghost[i]) continue;  // another part advances it
    Rigid_Body rb;
    std::memcpy(&rb, src + i * sizeof rb, sizeof rb);
    copy_state(rb, bodies[p.bodies[i]].state);
  }
}

}  // namespace cellphys::ppe
