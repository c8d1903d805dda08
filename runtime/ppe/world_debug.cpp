// What the last step saw, for display (debug overlays): its contacts with the normal force the
// step applied at each, each body's island, and the couplings decoupling cut. Read-only: nothing here
// feeds the step.
#include <algorithm>
#include <cmath>

#include "runtime/ppe/world_impl.h"

namespace cellphys::ppe {

namespace {

// The velocity after the step of body id's material point at world point p (zero for static
// geometry), its lever taken from the body's centre where the step began (the step moved it by h v).
void point_velocity(const std::vector<WorldBody>& bodies, uint32_t id, const float p[3], double h, double out[3]) {
  out[0] = out[1] = out[2] = 0;
  if (id == kWorldBody || id >= bodies.size() || bodies[id].is_static) return;
  const BodyState& s = bodies[id].state;
  double r[3];
  for (int i = 0; i < 3; ++i) r[i] = double(p[i]) - (double(s.position[i]) - h * s.velocity[i]);
  const float* w = s.angular_velocity;
  out[0] = s.velocity[0] + w[1] * r[2] - w[2] * r[1];
  out[1] = s.velocity[1] + w[2] * r[0] - w[0] * r[2];
  out[2] = s.velocity[2] + w[0] * r[1] - w[1] * r[0];
}

// The normal force (N) the step's linear solve applied at a contact: the normal part of the
// contact descriptor (codegen/descriptors/forces/contact.yaml) linearised as the implicit step
// linearises it, about the step's start, and taken at the separating speed the step ended with.
// The kernels keep no per-contact force, and the spring's k·depth alone says nothing of a
// landing (a gap contact has no depth) or of the damper: this is what moved the bodies.
float step_normal_force(const WorldContact& c, const std::vector<WorldBody>& bodies, const WorldSettings& s) {
  const auto& g = s.globals;
  const double h = s.dt;
  double va[3], vb[3];
  point_velocity(bodies, c.a, c.point.point, h, va);
  point_velocity(bodies, c.b, c.point.point, h, vb);
  const float* n = c.point.normal;
  const double vn = (vb[0] - va[0]) * n[0] + (vb[1] - va[1]) * n[1] + (vb[2] - va[2]) * n[2];
  const double omega = 2 * 3.14159265358979323846 * g.contact_hertz;
  const double m = std::max(c.load, c.mass);
  const double k = g.contact_stiffness > 0 ? double(g.contact_stiffness) : m * omega * omega;
  const double damp = g.contact_damping > 0 ? double(g.contact_damping) : 2 * double(g.contact_damping_ratio) * m * omega;
  const double pen = c.point.penetration, fall = c.fall;
  const double end_depth = pen - h * (vn + fall);  // the overlap at the step's end, with gravity's fall
  if (pen > 0) {
    // Deeper than its hold the spring is flat (the push stage takes the rest).
    const double held = pen > c.hold ? double(c.hold) : pen - h * vn;
    const double pushed = k * held - damp * vn;
    return static_cast<float>(end_depth > 0 ? pushed : std::max(0.0, pushed));
  }
  const bool closing = vn <= g.contact_rest_speed && end_depth >= 0;
  return closing ? static_cast<float>((damp + h * k) * (pen / h - vn)) : 0.0f;
}

DebugContact view(const WorldContact& c, const std::vector<WorldBody>& bodies, const WorldSettings& s) {
  DebugContact d{};
  d.a = c.a;
  d.b = c.b;
  std::copy(c.point.point, c.point.point + 3, d.point);
  std::copy(c.point.normal, c.point.normal + 3, d.normal);
  d.depth = c.point.penetration;
  d.force = step_normal_force(c, bodies, s);
  return d;
}

}  // namespace

std::vector<DebugContact> World::debug_contacts() const {
  const Impl& w = *impl_;
  auto awake = [&](uint32_t id) {
    return id < w.bodies.size() && w.bodies[id].alive && !w.bodies[id].is_static && w.bodies[id].awake;
  };
  std::vector<DebugContact> out;
  // The step's contacts between bodies that went to sleep in it are their group's now.
  for (const WorldContact& c : w.contacts)
    if (awake(c.a) || awake(c.b)) out.push_back(view(c, w.bodies, settings_));
  for (const SleepGroup& g : w.sleeping.groups)
    if (!g.bodies.empty())
      for (const WorldContact& c : g.contacts) out.push_back(view(c, w.bodies, settings_));
  return out;
}

uint32_t World::last_island(BodyId id) const {
  const Impl& w = *impl_;
  return id < w.island_of.size() && w.live(id).awake ? w.island_of[id] : kNoIsland;
}

bool World::island_decoupled(uint32_t island) const {
  return island < impl_->island_decoupled.size() && impl_->island_decoupled[island] != 0;
}

const std::vector<CutCoupling>& World::cut_couplings() const { return impl_->cut; }

void cut_couplings_of(const DecoupledIslands& d, const std::vector<WorldContact>& contacts,
                      const std::vector<WorldForce>& forces, std::vector<uint32_t>& ids, std::vector<CutCoupling>& out) {
  out.clear();
  // A cut coupling goes into the part on each side of the cut, an uncut one into one part: the
  // ids that repeat among an island's parts, sorted.
  auto repeated = [&](const std::vector<IslandContent>& parts, std::vector<uint32_t> IslandContent::*member, auto emit) {
    ids.clear();
    for (const IslandContent& p : parts) ids.insert(ids.end(), (p.*member).begin(), (p.*member).end());
    std::sort(ids.begin(), ids.end());
    for (size_t k = 0; k + 1 < ids.size(); ++k)
      if (ids[k] == ids[k + 1] && (k == 0 || ids[k - 1] != ids[k])) emit(ids[k]);
  };
  for (size_t i = 0; i < d.used.size(); ++i) {
    if (!d.is_split(i)) continue;
    const auto island = static_cast<uint32_t>(i);
    repeated(d.parts[i], &IslandContent::contacts, [&](uint32_t c) {
      CutCoupling cut{contacts[c].a, contacts[c].b, kNoForce, {}, island};
      std::copy(contacts[c].point.point, contacts[c].point.point + 3, cut.point);
      out.push_back(cut);
    });
    repeated(d.parts[i], &IslandContent::forces,
             [&](uint32_t f) { out.push_back(CutCoupling{forces[f].a, forces[f].b, f, {}, island}); });
  }
}

}  // namespace cellphys::ppe
