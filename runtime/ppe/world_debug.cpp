// What the last step saw, for display (debug overlays): its contacts with an estimate of their
// normal force, and each body's island. Read-only: nothing here feeds the step.
#include <algorithm>
#include <cmath>

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

}  // namespace cellphys::ppe
