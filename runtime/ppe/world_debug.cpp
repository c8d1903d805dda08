// What the last step saw, for display (debug overlays): its contacts with an estimate of their
// normal force, each body's island, and the couplings decoupling cut. Read-only: nothing here
// feeds the step.
#include <algorithm>
#include <cmath>
#include <map>

#include "runtime/ppe/world_impl.h"

namespace cellphys::ppe {

namespace {

DebugContact view(const WorldContact& c, const WorldSettings& s) {
  DebugContact d{};
  d.a = c.a;
  d.b = c.b;
  std::copy(c.point.point, c.point.point + 3, d.point);
  std::copy(c.point.normal, c.point.normal + 3, d.normal);
  d.depth = c.point.penetration;
  // The contact's spring as the descriptor tunes it (docs/contacts.md): k = m ω², m the larger
  // of the point's effective mass and its load, unless contact.stiffness fixes k.
  const double omega = 2 * 3.14159265358979323846 * s.globals.contact_hertz;
  const double k = s.globals.contact_stiffness > 0 ? s.globals.contact_stiffness
                                                   : double(std::max(c.mass, c.load)) * omega * omega;
  d.force = static_cast<float>(k * std::max(0.0, double(c.point.penetration)));
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
    if (awake(c.a) || awake(c.b)) out.push_back(view(c, settings_));
  for (const SleepGroup& g : w.sleeping.groups)
    if (!g.bodies.empty())
      for (const WorldContact& c : g.contacts) out.push_back(view(c, settings_));
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

std::vector<CutCoupling> cut_couplings_of(const DecoupledIslands& d, const std::vector<WorldContact>& contacts,
                                          const std::vector<WorldForce>& forces) {
  std::vector<CutCoupling> out;
  for (size_t i = 0; i < d.parts.size(); ++i) {
    if (d.parts[i].size() < 2) continue;
    // A cut coupling goes into the part on each side of the cut; an uncut one into one part.
    std::map<uint32_t, int> contact_parts, force_parts;
    for (const IslandContent& p : d.parts[i]) {
      for (uint32_t c : p.contacts) ++contact_parts[c];
      for (uint32_t f : p.forces) ++force_parts[f];
    }
    const auto island = static_cast<uint32_t>(i);
    for (const auto& [c, n] : contact_parts)
      if (n > 1) {
        CutCoupling cut{contacts[c].a, contacts[c].b, kNoForce, {}, island};
        std::copy(contacts[c].point.point, contacts[c].point.point + 3, cut.point);
        out.push_back(cut);
      }
    for (const auto& [f, n] : force_parts)
      if (n > 1) out.push_back(CutCoupling{forces[f].a, forces[f].b, f, {}, island});
  }
  return out;
}

}  // namespace cellphys::ppe
