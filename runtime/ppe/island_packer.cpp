#include "runtime/ppe/island_packer.h"

#include <algorithm>
#include <array>
#include <cstring>

#include "runtime/ppe/world.h"
#include "runtime/spu/force_eval.h"
#include "runtime/spu/workspace.h"

namespace cellphys::ppe {

using namespace cellphys::gen;

namespace {

using Wrench = std::pair<uint32_t, std::array<float, 6>>;  // world id, force and torque

Rigid_Body_Fields fields_of(const WorldBody& b) {
  Rigid_Body_Fields f;
  std::copy(b.position, b.position + 3, f.position);
  std::copy(b.orientation, b.orientation + 4, f.orientation);
  std::copy(b.velocity, b.velocity + 3, f.velocity);
  std::copy(b.angular_velocity, b.angular_velocity + 3, f.angular_velocity);
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

int32_t local_of(const std::vector<uint32_t>& bodies, uint32_t id) {
  if (id == kWorldBody) return -1;
  const auto it = std::lower_bound(bodies.begin(), bodies.end(), id);
  return it != bodies.end() && *it == id ? static_cast<int32_t>(it - bodies.begin()) : -2;
}

Contact_Force contact_instance(const WorldContact& c, int32_t a, int32_t b) {
  Contact_Force_Fields f;
  std::copy(c.point.point, c.point.point + 3, f.point);
  std::copy(c.point.normal, c.point.normal + 3, f.normal);
  f.penetration = c.point.penetration;
  f.friction = c.friction;
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

PackedIsland pack(const PackContext& pc, const IslandContent& isl, const std::vector<Wrench>& wrenches) {
  const WorldSettings& s = pc.settings;
  spu::IslandBuilder ib;
  ib.set_step(s.dt);
  ib.set_integrator(s.integrator);
  ib.set_solver(static_cast<uint32_t>(s.solver));
  ib.set_tolerance(s.tolerance);
  ib.set_max_halvings(s.max_halvings);
  Island_Params& g = ib.params();
  std::copy(s.gravity, s.gravity + 3, g.gravity);
  g.contact_stiffness = s.contact_stiffness;
  g.contact_damping = s.contact_damping;
  g.slip_velocity = s.slip_velocity;
  PackedIsland p;
  p.bodies = isl.bodies;
  for (uint32_t id : isl.bodies) {
    const WorldBody& b = pc.bodies[id];
    const int local = ib.add_body(fields_of(b));
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
  if (s.gravity[0] != 0 || s.gravity[1] != 0 || s.gravity[2] != 0) ib.add_global(ForceType::gravity);
  // contacts grouped by body pair, in a fixed order
  std::vector<uint32_t> cs = isl.contacts;
  std::stable_sort(cs.begin(), cs.end(), [&](uint32_t x, uint32_t y) {
    const WorldContact &a = pc.contacts[x], &b = pc.contacts[y];
    return a.a != b.a ? a.a < b.a : a.b != b.b ? a.b < b.b : x < y;
  });
  for (uint32_t c : cs) {
    const WorldContact& wc = pc.contacts[c];
    ib.add(ForceType::contact, contact_instance(wc, local_of(p.bodies, wc.a), local_of(p.bodies, wc.b)));
  }
  for (uint32_t fid : isl.forces) {
    const WorldForce& f = pc.forces[fid];
    const ForceInfo& info = kForceTable[static_cast<int>(f.type)];
    std::vector<unsigned char> inst = f.instance;
    set_bodies(info, inst, local_of(p.bodies, f.a), local_of(p.bodies, f.b));
    ib.add_force(f.type, inst.data(), inst.size());
  }
  for (const Wrench& w : wrenches) {
    Applied_Wrench_Force_Fields a;
    std::copy(w.second.begin(), w.second.begin() + 3, a.force_world);
    std::copy(w.second.begin() + 3, w.second.end(), a.torque_world);
    a.body_a = local_of(p.bodies, w.first);
    Applied_Wrench_Force ap;
    pack(a, ap);
    ib.add(ForceType::applied_wrench, ap);
  }
  p.image = ib.finish();
  return p;
}

bool fits(const PackedIsland& p, size_t capacity) {
  const spu::IslandView v = spu::view_island(const_cast<unsigned char*>(p.image.data()));
  return spu::footprint(spu::counts_of(v)).total <= capacity;
}

// F on both bodies of a coupling at the start-of-step state.
void coupling_wrench(const PackContext& pc, ForceType type, std::vector<unsigned char> inst, uint32_t a, uint32_t b,
                     std::vector<Wrench>& side_a, std::vector<Wrench>& side_b) {
  Rigid_Body rb[2];
  pack(fields_of(pc.bodies[a]), rb[0]);
  pack(fields_of(pc.bodies[b]), rb[1]);
  Island_Params g{};
  std::copy(pc.settings.gravity, pc.settings.gravity + 3, g.gravity);
  g.contact_stiffness = pc.settings.contact_stiffness;
  g.contact_damping = pc.settings.contact_damping;
  g.slip_velocity = pc.settings.slip_velocity;
  set_bodies(kForceTable[static_cast<int>(type)], inst, 0, 1);
  float F[12];
  spu::evaluate_instance(type, inst.data(), rb, g, F);
  std::array<float, 6> wa, wb;
  std::copy(F, F + 6, wa.begin());
  std::copy(F + 6, F + 12, wb.begin());
  side_a.emplace_back(a, wa);
  side_b.emplace_back(b, wb);
}

void split(const PackContext& pc, IslandContent isl, std::vector<Wrench> wrenches, std::vector<PackedIsland>& out,
           uint32_t& cut) {
  PackedIsland p = pack(pc, isl, wrenches);
  if (isl.bodies.size() <= 1 || fits(p, pc.settings.local_store_bytes)) {
    out.push_back(std::move(p));
    return;
  }
  // Cut across the longest extent at the median body: a plane cuts few couplings.
  float lo[3] = {1e30f, 1e30f, 1e30f}, hi[3] = {-1e30f, -1e30f, -1e30f};
  for (uint32_t id : isl.bodies)
    for (int k = 0; k < 3; ++k) lo[k] = std::min(lo[k], pc.bodies[id].position[k]), hi[k] = std::max(hi[k], pc.bodies[id].position[k]);
  int axis = 0;
  for (int k = 1; k < 3; ++k)
    if (hi[k] - lo[k] > hi[axis] - lo[axis]) axis = k;
  std::vector<uint32_t> order = isl.bodies;
  std::stable_sort(order.begin(), order.end(), [&](uint32_t x, uint32_t y) {
    return pc.bodies[x].position[axis] < pc.bodies[y].position[axis];
  });
  IslandContent half[2];
  half[0].bodies.assign(order.begin(), order.begin() + order.size() / 2);
  half[1].bodies.assign(order.begin() + order.size() / 2, order.end());
  for (IslandContent& h : half) std::sort(h.bodies.begin(), h.bodies.end());
  auto side = [&](uint32_t id) { return std::binary_search(half[0].bodies.begin(), half[0].bodies.end(), id) ? 0 : 1; };
  std::vector<Wrench> w[2];
  for (const Wrench& x : wrenches) w[side(x.first)].push_back(x);
  for (uint32_t c : isl.contacts) {
    const WorldContact& wc = pc.contacts[c];
    const int sa = side(wc.a);
    if (wc.b == kWorldBody || side(wc.b) == sa) {
      half[sa].contacts.push_back(c);
      continue;
    }
    Contact_Force inst = contact_instance(wc, 0, 1);
    std::vector<unsigned char> bytes(reinterpret_cast<unsigned char*>(&inst), reinterpret_cast<unsigned char*>(&inst) + sizeof inst);
    coupling_wrench(pc, ForceType::contact, bytes, wc.a, wc.b, w[sa], w[1 - sa]);
    ++cut;
  }
  for (uint32_t fid : isl.forces) {
    const WorldForce& f = pc.forces[fid];
    const int sa = side(f.a);
    if (f.b == kWorldBody || side(f.b) == sa) {
      half[sa].forces.push_back(fid);
      continue;
    }
    coupling_wrench(pc, f.type, f.instance, f.a, f.b, w[sa], w[1 - sa]);
    ++cut;
  }
  split(pc, std::move(half[0]), std::move(w[0]), out, cut);
  split(pc, std::move(half[1]), std::move(w[1]), out, cut);
}

}  // namespace

void pack_decoupled(const PackContext& pc, IslandContent island, std::vector<PackedIsland>& out, uint32_t& cut_couplings) {
  split(pc, std::move(island), {}, out, cut_couplings);
}

void unpack_island(const PackedIsland& p, std::vector<WorldBody>& bodies) {
  const size_t n = p.bodies.size();
  const unsigned char* src = p.result.data() + p.result.size() - n * sizeof(Rigid_Body);
  for (size_t i = 0; i < n; ++i) {
    Rigid_Body rb;
    std::memcpy(&rb, src + i * sizeof rb, sizeof rb);
    WorldBody& b = bodies[p.bodies[i]];
    std::copy(rb.position, rb.position + 3, b.position);
    std::copy(rb.orientation, rb.orientation + 4, b.orientation);
    std::copy(rb.velocity, rb.velocity + 3, b.velocity);
    std::copy(rb.angular_velocity, rb.angular_velocity + 3, b.angular_velocity);
  }
}

}  // namespace cellphys::ppe
