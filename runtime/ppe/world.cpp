#include "runtime/ppe/world.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <numeric>

#include "runtime/ppe/island_packer.h"
#include "runtime/ppe/mass_properties.h"
#include "runtime/ppe/settings.h"
#include "runtime/ppe/world_impl.h"
#include "runtime/spu/narrow_phase.h"
#include "runtime/spu/rigid_motion.h"

namespace cellphys::ppe {

using namespace cellphys::gen;
using Clock = std::chrono::steady_clock;

namespace {

double ms_since(Clock::time_point t) { return std::chrono::duration<double, std::milli>(Clock::now() - t).count(); }

bool finite(const float* p, int n) {
  for (int i = 0; i < n; ++i)
    if (!std::isfinite(p[i])) return false;
  return true;
}

// The seed's wire tables for one packed island (StepStats): per body 22 floats and its
// shape's geometry, or 25 floats with a dictionary reference, out; 13 floats back. The
// island's header, force and contact records go out in both forms.
void count_wire_tables(const PackedIsland& p, const ShapeDictionary& shapes, StepStats& st) {
  const uint64_t n = p.bodies.size();
  const uint64_t shared = p.image.size() - n * sizeof(Rigid_Body);
  uint64_t geometry = 0;
  const spu::IslandView v = spu::view_island(const_cast<unsigned char*>(p.image.data()));
  for (uint64_t i = 0; i < n; ++i) geometry += shapes.bytes(v.bodies[i].shape_index);
  st.island_bodies += n;
  st.island_bytes_shared += shared;
  st.wire_table_to_nodes += n * sizeof(Wire_Body_To_Node) + geometry + shared;
  st.wire_table_to_nodes_compressed += n * sizeof(Wire_Body_To_Node_Compressed) + shared;
  st.wire_table_from_nodes += n * sizeof(Wire_Node_To_Dispatcher);
  st.image_bytes += p.image.size();
  st.result_bytes += p.result.size();
}

// A result is sound when its header belongs to the island and its bytes match their
// checksum. A kernel refuses a sound image only when it does not fit (the same anywhere), so
// a "malformed" refusal means the image was damaged on its way.
bool sound_result(const PackedIsland& p, const spu::IslandReport& r) {
  const uint32_t n = static_cast<uint32_t>(p.bodies.size());
  Island_Result h;
  if (p.result.size() < sizeof h) return false;
  std::memcpy(&h, p.result.data(), sizeof h);
  if (h.magic != spu::kResultMagic || h.num_bodies != n || h.status != static_cast<uint32_t>(r.status)) return false;
  switch (r.status) {
    case spu::IslandStatus::does_not_fit: return true;
    case spu::IslandStatus::malformed: return false;
    case spu::IslandStatus::ok:
    case spu::IslandStatus::failed: break;
  }
  if (h.total_bytes != spu::result_bytes(n) || p.result.size() != h.total_bytes) return false;
  const size_t head = spu::align16(sizeof(Island_Result)), steps = size_t{n} * sizeof(Rigid_Body_Step);
  const unsigned char* base = p.result.data();
  return spu::checksum(base + head + steps, size_t{n} * sizeof(Rigid_Body), spu::checksum(base + head, steps)) == h.checksum;
}

}  // namespace

World::World(WorldSettings settings) : settings_(settings), impl_(std::make_unique<Impl>()) {
  validate_settings(settings_);
}
World::~World() = default;

void World::set_runner(std::shared_ptr<IslandRunner> runner) { impl_->runner = std::move(runner); }
IslandRunner* World::runner() const { return impl_->runner.get(); }

void World::set_settings(const WorldSettings& s) {
  validate_settings(s);
  settings_ = s;
}

BodyId World::add_body(const BodyDesc& d) {
  warnings_.clear();
  const std::string who = "body " + std::to_string(impl_->bodies.size());
  if (d.shape >= shapes_.size()) throw WorldError(who + ": shape " + std::to_string(d.shape) + " does not exist");
  if (!(d.scale > 0.0f) || !std::isfinite(d.scale)) throw WorldError(who + ": scale must be positive and finite");
  if (!finite(d.position, 3) || !finite(d.orientation, 4) || !finite(d.velocity, 3) || !finite(d.angular_velocity, 3))
    throw WorldError(who + ": position, orientation and velocities must be finite");
  if (!(d.friction >= 0.0f) || !std::isfinite(d.friction)) throw WorldError(who + ": friction must be >= 0");
  if (!(d.linear_damping >= 0.0f) || !(d.angular_damping >= 0.0f) || !std::isfinite(d.linear_damping) ||
      !std::isfinite(d.angular_damping))
    throw WorldError(who + ": damping must be >= 0");
  const double qn = std::sqrt(double(d.orientation[0]) * d.orientation[0] + double(d.orientation[1]) * d.orientation[1] +
                              double(d.orientation[2]) * d.orientation[2] + double(d.orientation[3]) * d.orientation[3]);
  if (qn < 1e-6) throw WorldError(who + ": orientation is a zero quaternion");
  WorldBody b;
  b.alive = true;
  b.shape = d.shape;
  b.scale = d.scale;
  b.friction = d.friction;
  b.linear_damping = d.linear_damping;
  b.angular_damping = d.angular_damping;
  const bool plane = shapes_.type(d.shape) == spu::ShapeType::plane;
  b.is_static = d.is_static || plane;
  std::copy(d.position, d.position + 3, b.position);
  for (int k = 0; k < 4; ++k) b.orientation[k] = static_cast<float>(d.orientation[k] / qn);
  if (std::fabs(qn - 1.0) > 1e-4) warnings_.push_back(who + ": orientation was not a unit quaternion; normalised");
  if (!b.is_static) {
    std::copy(d.velocity, d.velocity + 3, b.velocity);
    std::copy(d.angular_velocity, d.angular_velocity + 3, b.angular_velocity);
    if (d.mass > 0.0f && std::isfinite(d.mass)) {
      b.mass = d.mass;
    } else if (d.mass != 0.0f) {
      throw WorldError(who + ": mass must be positive and finite");
    } else if (!(d.density > 0.0f) || !std::isfinite(d.density)) {
      throw WorldError(who + ": a dynamic body needs a positive mass or density");
    }
    const BodyMass m = body_mass(shapes_, d.shape, d.scale, d.mass, d.density);  // throws ShapeError on bad input
    b.mass = m.mass;
    std::copy(m.inertia, m.inertia + 6, b.inertia);
    if (d.has_inertia) {
      if (!finite(d.inertia, 6) || !(d.inertia[0] > 0) || !(d.inertia[1] > 0) || !(d.inertia[2] > 0))
        throw WorldError(who + ": inertia needs positive, finite principal moments");
      std::copy(d.inertia, d.inertia + 6, b.inertia);
    }
    if (!invert_inertia(b.inertia, b.inverse_inertia)) throw WorldError(who + ": inertia tensor is not invertible");
  }
  impl_->bodies.push_back(b);
  return static_cast<BodyId>(impl_->bodies.size() - 1);
}

void World::remove_body(BodyId id) {
  WorldBody& b = impl_->live(id);
  impl_->wake(id);
  for (WorldForce& f : impl_->forces)
    if (f.alive && (f.a == id || f.b == id)) {
      if (f.a != id) impl_->wake(f.a);
      if (f.b != id && f.b != kWorldBody) impl_->wake(f.b);
      f.alive = false;
    }
  b.alive = false;
}

ForceId World::add_force(const std::string& type, BodyId a, BodyId b, const ForceParams& params) {
  warnings_.clear();
  int t = -1;
  for (int k = 0; k < kNumForceTypes; ++k)
    if (type == kForceTable[k].name) t = k;
  if (t < 0) {
    std::string known;
    for (const ForceInfo& f : kForceTable) known += (known.empty() ? "" : ", ") + std::string(f.name);
    throw WorldError("unknown force type '" + type + "' (known: " + known + ")");
  }
  const ForceInfo& info = kForceTable[t];
  if (info.kind == ForceKind::global) throw WorldError("force " + type + " is global: it is set in the world settings");
  const WorldBody& ba = impl_->live(a);
  if (ba.is_static) throw WorldError("force " + type + ": body a (" + body_name(a) + ") is static");
  if (info.kind == ForceKind::binary) {
    if (b == kWorldBody) {
      if (!info.world_anchor) throw WorldError("force " + type + " cannot be anchored to the world");
    } else {
      const WorldBody& bb = impl_->live(b);
      if (b == a) throw WorldError("force " + type + ": a and b are the same body");
      if (bb.is_static) throw WorldError("force " + type + ": body b (" + body_name(b) + ") is static; use \"world\"");
    }
  } else if (b != kWorldBody) {
    throw WorldError("force " + type + " acts on one body: b must be the world");
  }
  WorldForce f;
  f.alive = true;
  f.type = static_cast<ForceType>(t);
  f.a = a;
  f.b = info.kind == ForceKind::binary ? b : kWorldBody;
  f.instance.assign(info.instance_size, 0);
  for (const auto& [name, values] : params) {
    const ParamInfo* p = nullptr;
    for (uint32_t k = 0; k < info.num_params; ++k)
      if (name == info.params[k].name) p = &info.params[k];
    if (!p) throw WorldError("force " + type + ": unknown parameter '" + name + "'");
    if (values.size() != p->lanes)
      throw WorldError("force " + type + ": parameter '" + name + "' takes " + std::to_string(p->lanes) + " number(s)");
    if (!finite(values.data(), static_cast<int>(values.size())))
      throw WorldError("force " + type + ": parameter '" + name + "' is not finite");
    for (float v : values)
      if (!p->admits(v))
        throw WorldError("force " + type + ": parameter '" + name + "' must be " + p->min_relation() + " " + std::to_string(p->min));
    std::memcpy(f.instance.data() + p->offset, values.data(), 4 * values.size());
  }
  impl_->wake(a);
  if (f.b != kWorldBody) impl_->wake(f.b);
  impl_->forces.push_back(std::move(f));
  return static_cast<ForceId>(impl_->forces.size() - 1);
}

void World::remove_force(ForceId id) {
  if (id >= impl_->forces.size() || !impl_->forces[id].alive) throw WorldError("force " + std::to_string(id) + " does not exist");
  WorldForce& f = impl_->forces[id];
  impl_->wake(f.a);
  if (f.b != kWorldBody) impl_->wake(f.b);
  f.alive = false;
}

BodyState World::state(BodyId id) const {
  const WorldBody& b = impl_->live(id);
  BodyState s;
  std::copy(b.position, b.position + 3, s.position);
  std::copy(b.orientation, b.orientation + 4, s.orientation);
  std::copy(b.velocity, b.velocity + 3, s.velocity);
  std::copy(b.angular_velocity, b.angular_velocity + 3, s.angular_velocity);
  return s;
}

void World::set_state(BodyId id, const BodyState& s) {
  warnings_.clear();
  WorldBody& b = impl_->live(id);
  if (!finite(s.position, 3) || !finite(s.orientation, 4) || !finite(s.velocity, 3) || !finite(s.angular_velocity, 3))
    throw WorldError(body_name(id) + ": state must be finite");
  const double qn = std::sqrt(double(s.orientation[0]) * s.orientation[0] + double(s.orientation[1]) * s.orientation[1] +
                              double(s.orientation[2]) * s.orientation[2] + double(s.orientation[3]) * s.orientation[3]);
  if (qn < 1e-6) throw WorldError(body_name(id) + ": orientation is a zero quaternion");
  if (std::fabs(qn - 1.0) > 1e-4) warnings_.push_back(body_name(id) + ": orientation was not a unit quaternion; normalised");
  std::copy(s.position, s.position + 3, b.position);
  for (int k = 0; k < 4; ++k) b.orientation[k] = static_cast<float>(s.orientation[k] / qn);
  if (!b.is_static) {
    std::copy(s.velocity, s.velocity + 3, b.velocity);
    std::copy(s.angular_velocity, s.angular_velocity + 3, b.angular_velocity);
  }
  impl_->wake(id);
}

void World::apply_impulse(BodyId id, const float impulse[3], const float point[3]) {
  WorldBody& b = impl_->live(id);
  if (!finite(impulse, 3) || !finite(point, 3)) throw WorldError(body_name(id) + ": impulse and point must be finite");
  if (b.is_static) throw WorldError(body_name(id) + " is static");
  impl_->wake(id);
  const spu::Vec3d r = {point[0] - double(b.position[0]), point[1] - double(b.position[1]), point[2] - double(b.position[2])};
  const spu::Vec3d J = {impulse[0], impulse[1], impulse[2]};
  const spu::Vec3d L = {r.y * J.z - r.z * J.y, r.z * J.x - r.x * J.z, r.x * J.y - r.y * J.x};
  const spu::Quat q{b.orientation[0], b.orientation[1], b.orientation[2], b.orientation[3]};
  const spu::Vec3d dw = spu::mul(spu::rotate_sym(spu::quat_to_matrix(q), b.inverse_inertia), L);
  for (int k = 0; k < 3; ++k) b.velocity[k] += static_cast<float>(impulse[k] / b.mass);
  b.angular_velocity[0] += float(dw.x), b.angular_velocity[1] += float(dw.y), b.angular_velocity[2] += float(dw.z);
}

bool World::is_awake(BodyId id) const { return impl_->live(id).awake; }
bool World::is_static(BodyId id) const { return impl_->live(id).is_static; }
float World::mass(BodyId id) const { return impl_->live(id).mass; }
const float* World::inertia_body(BodyId id) const { return impl_->live(id).inertia; }

std::vector<BodyId> World::bodies() const {
  std::vector<BodyId> ids;
  for (BodyId i = 0; i < impl_->bodies.size(); ++i)
    if (impl_->bodies[i].alive) ids.push_back(i);
  return ids;
}

size_t World::num_bodies() const {
  return static_cast<size_t>(std::count_if(impl_->bodies.begin(), impl_->bodies.end(), [](const WorldBody& b) { return b.alive; }));
}

double World::kinetic_energy() const {
  double e = 0;
  for (const WorldBody& b : impl_->bodies) {
    if (!b.alive || b.is_static) continue;
    e += 0.5 * b.mass * (double(b.velocity[0]) * b.velocity[0] + double(b.velocity[1]) * b.velocity[1] +
                         double(b.velocity[2]) * b.velocity[2]);
    const spu::Quat q{b.orientation[0], b.orientation[1], b.orientation[2], b.orientation[3]};
    const spu::Vec3d w = {b.angular_velocity[0], b.angular_velocity[1], b.angular_velocity[2]};
    const spu::Vec3d Iw = spu::mul(spu::rotate_sym(spu::quat_to_matrix(q), b.inertia), w);
    e += 0.5 * (w.x * Iw.x + w.y * Iw.y + w.z * Iw.z);
  }
  return e;
}

uint64_t World::state_hash() const {
  uint64_t h = 0xCBF29CE484222325ull;
  for (const WorldBody& b : impl_->bodies) {
    if (!b.alive) continue;
    const float* parts[4] = {b.position, b.orientation, b.velocity, b.angular_velocity};
    const int n[4] = {3, 4, 3, 3};
    for (int p = 0; p < 4; ++p)
      for (int k = 0; k < n[p]; ++k) {
        uint32_t bits;
        std::memcpy(&bits, parts[p] + k, 4);
        h = (h ^ bits) * 0x100000001B3ull;
      }
  }
  return h;
}

const StepStats& World::step() {
  Impl& w = *impl_;
  StepStats st;
  st.step = stats_.step + 1;
  const auto t_step = Clock::now();
  const uint32_t n = static_cast<uint32_t>(w.bodies.size());

  // 1. Collision. Broad phase: boxes, culled against the simulated region.
  auto t = Clock::now();
  w.boxes.resize(n);
  w.reach.assign(n, 0.0f);
  w.kinds.assign(n, BoxKind::none);
  std::vector<uint32_t> planes;
  for (uint32_t i = 0; i < n; ++i) {
    const WorldBody& b = w.bodies[i];
    if (!b.alive) continue;
    ++st.bodies;
    if (b.is_static) ++st.static_bodies;
    if (shapes_.type(b.shape) == spu::ShapeType::plane) {
      planes.push_back(i);
      continue;
    }
    shapes_.world_aabb(b.shape, pose_of(b), w.boxes[i].min, w.boxes[i].max);
    // Speculative reach: how far the body can close on another within the step (its speed,
    // and the spin of its farthest point, times dt). Boxes grow by it plus half the slop, so
    // a pair is found when its gap may close to within the slop: fast bodies meet contacts
    // before they tunnel, resting ones carry none that cannot act.
    const Aabb& B = w.boxes[i];
    const double rx = 0.5 * (double(B.max[0]) - B.min[0]), ry = 0.5 * (double(B.max[1]) - B.min[1]),
                 rz = 0.5 * (double(B.max[2]) - B.min[2]);
    const double speed = std::sqrt(double(b.velocity[0]) * b.velocity[0] + double(b.velocity[1]) * b.velocity[1] +
                                   double(b.velocity[2]) * b.velocity[2]);
    const double spin = std::sqrt(double(b.angular_velocity[0]) * b.angular_velocity[0] +
                                  double(b.angular_velocity[1]) * b.angular_velocity[1] +
                                  double(b.angular_velocity[2]) * b.angular_velocity[2]);
    w.reach[i] = b.is_static ? 0.0f
                             : static_cast<float>(settings_.dt * (speed + spin * std::sqrt(rx * rx + ry * ry + rz * rz)) +
                                                  settings_.contact_margin);
    const float grow = w.reach[i] + 0.5f * settings_.globals.contact_slop;
    for (int k = 0; k < 3; ++k) w.boxes[i].min[k] -= grow, w.boxes[i].max[k] += grow;
    if (!inside_region(w.boxes[i], settings_.region_min, settings_.region_max)) {
      if (!b.is_static) ++st.outside_region;
      continue;
    }
    w.kinds[i] = b.is_static ? BoxKind::fixed : b.awake ? BoxKind::awake : BoxKind::asleep;
    ++st.broad_phase_boxes;
  }
  st.times.broad_ms = ms_since(t);
  // Mid phase: sort and sweep, plus every awake body against every plane.
  t = Clock::now();
  w.sap.find_pairs(w.boxes, w.kinds, w.pairs);
  for (uint32_t p : planes) {
    const spu::ShapeView& pv = shapes_.view(w.bodies[p].shape);
    for (uint32_t i = 0; i < n; ++i) {
      if (w.kinds[i] != BoxKind::awake) continue;
      const Aabb& B = w.boxes[i];
      double lowest = 0;  // the (grown) box corner furthest along -normal
      for (int k = 0; k < 3; ++k) lowest += pv.normal[k] * double(pv.normal[k] >= 0 ? B.min[k] : B.max[k]);
      if (lowest - pv.offset <= 0.5 * settings_.globals.contact_slop) w.pairs.emplace_back(std::min(i, p), std::max(i, p));
    }
  }
  std::sort(w.pairs.begin(), w.pairs.end());
  st.mid_phase_pairs = static_cast<uint32_t>(w.pairs.size());
  st.times.mid_ms = ms_since(t);
  // Narrow phase: contact manifolds, the dynamic body first, normals from a to b.
  t = Clock::now();
  w.contacts.clear();
  for (const auto& [i, j] : w.pairs) {
    uint32_t a = i, b = j;
    if (w.bodies[a].is_static) std::swap(a, b);
    spu::ContactPoint cp[spu::kMaxManifoldPoints];
    const float margin = settings_.globals.contact_slop + w.reach[a] + w.reach[b];
    const int k = spu::collide(shapes_.view(w.bodies[a].shape), pose_of(w.bodies[a]), shapes_.view(w.bodies[b].shape),
                               pose_of(w.bodies[b]), margin, cp);
    if (k > 0) ++st.narrow_phase_pairs;
    const float mu = std::sqrt(w.bodies[a].friction * w.bodies[b].friction);
    for (int c = 0; c < k; ++c)
      w.contacts.push_back({a, w.bodies[b].is_static ? kWorldBody : b, cp[c], mu});
  }
  st.times.narrow_ms = ms_since(t);

  // 2. Revise sleeping: contact with an awake body, or a force, wakes a sleeping group,
  // whose own contacts (unchanged while it slept) come back with it.
  t = Clock::now();
  for (bool changed = true; changed;) {
    changed = false;
    auto touch = [&](uint32_t x, uint32_t y) {
      if (y == kWorldBody) return;
      const WorldBody &bx = w.bodies[x], &by = w.bodies[y];
      if (bx.awake != by.awake && !bx.is_static && !by.is_static) {
        const uint32_t sleeper = bx.awake ? y : x;
        const int32_t g = w.bodies[sleeper].sleep_group;
        if (g >= 0) w.contacts.insert(w.contacts.end(), w.groups[g].contacts.begin(), w.groups[g].contacts.end());
        w.wake(sleeper);
        ++st.woken;
        changed = true;
      }
    };
    for (size_t c = 0; c < w.contacts.size(); ++c) touch(w.contacts[c].a, w.contacts[c].b);
    for (const WorldForce& f : w.forces)
      if (f.alive) touch(f.a, f.b);
  }
  st.times.sleep_ms = ms_since(t);

  // 3. Partition awake bodies into islands: contacts and binary forces join them.
  t = Clock::now();
  std::vector<uint32_t> parent(n);
  std::iota(parent.begin(), parent.end(), 0u);
  auto find = [&](uint32_t x) {
    while (parent[x] != x) x = parent[x] = parent[parent[x]];
    return x;
  };
  auto unite = [&](uint32_t x, uint32_t y) {
    x = find(x), y = find(y);
    if (x != y) parent[std::max(x, y)] = std::min(x, y);  // smallest slot is the root: deterministic
  };
  for (const WorldContact& c : w.contacts)
    if (c.b != kWorldBody && w.bodies[c.a].awake && w.bodies[c.b].awake) unite(c.a, c.b);
  for (const WorldForce& f : w.forces)
    if (f.alive && f.b != kWorldBody && w.bodies[f.a].awake && w.bodies[f.b].awake) unite(f.a, f.b);
  std::vector<int32_t> island_of(n, -1);
  std::vector<IslandContent> islands;
  for (uint32_t i = 0; i < n; ++i) {
    const WorldBody& b = w.bodies[i];
    if (!b.alive || b.is_static) continue;
    if (!b.awake) {
      ++st.sleeping_bodies;
      continue;
    }
    ++st.active_bodies;
    const uint32_t r = find(i);
    if (island_of[r] < 0) island_of[r] = static_cast<int32_t>(islands.size()), islands.emplace_back();
    islands[island_of[r]].bodies.push_back(i);
  }
  for (uint32_t c = 0; c < w.contacts.size(); ++c)
    if (w.bodies[w.contacts[c].a].awake) islands[island_of[find(w.contacts[c].a)]].contacts.push_back(c);
  for (uint32_t f = 0; f < w.forces.size(); ++f)
    if (w.forces[f].alive && w.bodies[w.forces[f].a].awake) islands[island_of[find(w.forces[f].a)]].forces.push_back(f);
  st.islands = static_cast<uint32_t>(islands.size());
  st.contacts = static_cast<uint32_t>(w.contacts.size());
  st.times.islands_ms = ms_since(t);

  // 4. Decouple what does not fit a local store.
  t = Clock::now();
  std::vector<WorldBody> start;  // the start-of-step state, kept only when an island is split
  std::vector<std::vector<IslandContent>> parts(islands.size());
  size_t waves = 0;
  {
    const PackContext pc{w.bodies, w.forces, w.contacts, settings_, w.bodies};
    for (size_t k = 0; k < islands.size(); ++k) {
      parts[k] = decouple(pc, islands[k], st.cut_couplings);  // a copy: the sleep check below needs it
      if (parts[k].size() > 1) ++st.decoupled_islands;
      waves = std::max(waves, parts[k].size());
    }
  }
  if (waves > 1) start = w.bodies;
  const PackContext pc{w.bodies, w.forces, w.contacts, settings_, waves > 1 ? start : w.bodies};
  st.times.decouple_ms = ms_since(t);

  // 5 and 6. Pack, integrate on the workers, unpack. Wave k holds part k of every island: the
  // parts of a split island run in order, each from the start state against ghosts at the
  // latest velocities of the others (a block Gauss-Seidel sweep). Split islands sweep again
  // until no velocity changes by more than decouple_tolerance. A failed island keeps its state
  // (the kernel halved its step already); a split island with a part that failed in its last
  // sweep goes back to its start state whole, never half-stepped.
  std::vector<float> before;
  std::vector<uint8_t> part_failed(islands.size(), 0);  // split islands: a part failed this sweep
  for (uint32_t sweep = 0; sweep < std::max(1u, settings_.decouple_sweeps); ++sweep) {
    if (sweep > 0 && waves <= 1) break;
    std::fill(part_failed.begin(), part_failed.end(), uint8_t{0});
    if (waves > 1) {  // velocities at the end of the previous sweep
      before.clear();
      for (size_t k = 0; k < parts.size(); ++k)
        if (parts[k].size() > 1)
          for (uint32_t i : islands[k].bodies) before.insert(before.end(), w.bodies[i].velocity, w.bodies[i].velocity + 3);
    }
    for (size_t wave = 0; wave < waves; ++wave) {
      t = Clock::now();
      std::vector<PackedIsland> packed;
      std::vector<size_t> island_of_packed;
      for (size_t k = 0; k < parts.size(); ++k)
        if (wave < parts[k].size() && (sweep == 0 || parts[k].size() > 1)) {
          packed.push_back(pack_island(pc, parts[k][wave]));
          island_of_packed.push_back(k);
        }
      // largest first: the long islands start early on the workers
      std::vector<size_t> order(packed.size());
      std::iota(order.begin(), order.end(), size_t{0});
      std::stable_sort(order.begin(), order.end(),
                       [&](size_t x, size_t y) { return packed[x].image.size() > packed[y].image.size(); });
      std::vector<spu::IslandJob> jobs;
      for (size_t k : order) {
        PackedIsland& p = packed[k];
        p.result.assign(spu::result_bytes(static_cast<uint32_t>(p.bodies.size())), 0);
        jobs.push_back({p.image.data(), p.image.size(), p.result.data(), p.result.size()});
        count_wire_tables(p, shapes_, st);
      }
      st.times.pack_ms += ms_since(t);
      t = Clock::now();
      std::vector<spu::IslandReport> reports;
      IslandRunner& runner = w.islands_runner(settings_);
      runner.set_local_store(settings_.local_store_bytes);
      runner.run(jobs, reports);
      const TransportCounters tc = runner.last_transport();
      st.bytes_to_nodes += tc.bytes_to_nodes;
      st.bytes_from_nodes += tc.bytes_from_nodes;
      st.messages += tc.messages_to_nodes + tc.messages_from_nodes;
      st.bad_messages += tc.bad_messages;
      st.reassigned_islands += tc.reassigned_islands;
      st.dropped_nodes += tc.dropped_nodes;
      // Every result is checked before anything is unpacked; an unsound one (damaged on the
      // way, or refused by a node that was sent a sound image) is computed again here.
      for (size_t j = 0; j < order.size(); ++j) {
        PackedIsland& p = packed[order[j]];
        if (sound_result(p, reports[j])) continue;
        reports[j] = w.local_worker(settings_).step(p.image.data(), p.image.size(), p.result.data(), p.result.size());
        ++st.recomputed_islands;
      }
      st.times.integrate_ms += ms_since(t);
      t = Clock::now();
      for (size_t j = 0; j < order.size(); ++j) {
        const PackedIsland& p = packed[order[j]];
        const spu::IslandReport& r = reports[j];
        st.solver_iterations += r.solver_iterations;
        st.solves += r.solves;
        st.step_halvings = std::max(st.step_halvings, r.halvings);
        st.substeps += r.substeps;
        st.local_store_peak_bytes = std::max(st.local_store_peak_bytes, r.footprint.total);
        if (r.status != spu::IslandStatus::ok) {
          const size_t k = island_of_packed[order[j]];
          if (parts[k].size() > 1) part_failed[k] = 1;  // counted once, after the last sweep
          else ++st.failed_islands;
          continue;
        }
        unpack_island(p, w.bodies);
      }
      st.times.unpack_ms += ms_since(t);
    }
    if (waves <= 1) break;
    st.decouple_sweeps = sweep + 1;
    float change = 0;
    size_t at = 0;
    for (size_t k = 0; k < parts.size(); ++k)
      if (parts[k].size() > 1)
        for (uint32_t i : islands[k].bodies)
          for (int c = 0; c < 3; ++c) change = std::max(change, std::fabs(w.bodies[i].velocity[c] - before[at++]));
    st.decouple_change = change;
    const bool any_failed = std::find(part_failed.begin(), part_failed.end(), uint8_t{1}) != part_failed.end();
    if (sweep > 0 && change <= settings_.decouple_tolerance && !any_failed) break;
  }
  for (size_t k = 0; k < islands.size(); ++k)
    if (part_failed[k]) {
      ++st.failed_islands;
      for (uint32_t i : islands[k].bodies) w.bodies[i] = start[i];
    }
  t = Clock::now();
  // Sleep: an island whose bodies have all been slow for sleep_time goes to sleep together.
  if (settings_.sleeping) {
    const float lin2 = settings_.sleep_linear * settings_.sleep_linear, ang2 = settings_.sleep_angular * settings_.sleep_angular;
    for (const IslandContent& isl : islands) {
      bool all = true;
      for (uint32_t i : isl.bodies) {
        WorldBody& b = w.bodies[i];
        const float v2 = b.velocity[0] * b.velocity[0] + b.velocity[1] * b.velocity[1] + b.velocity[2] * b.velocity[2];
        const float a2 = b.angular_velocity[0] * b.angular_velocity[0] + b.angular_velocity[1] * b.angular_velocity[1] +
                         b.angular_velocity[2] * b.angular_velocity[2];
        b.sleep_timer = (v2 < lin2 && a2 < ang2) ? b.sleep_timer + settings_.dt : 0.0f;
        all = all && b.sleep_timer >= settings_.sleep_time;
      }
      if (!all || isl.bodies.empty()) continue;
      int32_t g;
      if (!w.free_groups.empty()) g = w.free_groups.back(), w.free_groups.pop_back();
      else g = static_cast<int32_t>(w.groups.size()), w.groups.emplace_back();
      SleepGroup& grp = w.groups[g];
      grp.bodies = isl.bodies;
      for (uint32_t c : isl.contacts) grp.contacts.push_back(w.contacts[c]);
      for (uint32_t i : isl.bodies) {
        WorldBody& b = w.bodies[i];
        b.awake = false;
        b.sleep_group = g;
        std::fill(b.velocity, b.velocity + 3, 0.0f);
        std::fill(b.angular_velocity, b.angular_velocity + 3, 0.0f);
      }
      st.fell_asleep += static_cast<uint32_t>(isl.bodies.size());
    }
  }
  st.times.unpack_ms += ms_since(t);  // with the sleep check
  st.times.total_ms = ms_since(t_step);
  stats_ = st;
  return stats_;
}

}  // namespace cellphys::ppe
