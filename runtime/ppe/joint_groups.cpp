#include "runtime/ppe/joint_groups.h"

#include "cellphys/gen/force_table.h"
#include "runtime/ppe/contact_loads.h"

namespace cellphys::ppe {

void JointGroups::build(const std::vector<WorldBody>& bodies, const std::vector<WorldForce>& forces) {
  root_.clear();
  auto dynamic = [&](uint32_t id) { return id != kWorldBody && id < bodies.size() && !bodies[id].is_static; };
  auto find = [&](uint32_t i) {
    while (root_[i] != i) i = root_[i] = root_[root_[i]];  // path halving
    return i;
  };
  for (const WorldForce& f : forces) {
    if (!f.alive || !gen::kForceTable[static_cast<int>(f.type)].joint || !dynamic(f.a) || !dynamic(f.b)) continue;
    if (root_.empty()) {
      root_.resize(bodies.size());
      for (uint32_t i = 0; i < root_.size(); ++i) root_[i] = i;
    }
    const uint32_t ra = find(f.a), rb = find(f.b);
    if (ra < rb) root_[rb] = ra;
    else root_[ra] = rb;
  }
  // Each body straight to its group's root, which (joined low under high) is its lowest id.
  for (uint32_t i = 0; i < root_.size(); ++i) root_[i] = root_[root_[i]];
}

void set_contact_hold_and_fall(const WorldSettings& s, const JointGroups& groups, std::vector<WorldContact>& contacts) {
  for (WorldContact& c : contacts) {
    const bool joined = groups.joined(c.a, c.b);
    c.hold = joined ? s.contact_joined_hold_depth : s.globals.contact_hold_depth;
    c.fall = joined ? 0.0f : gravity_fall(c.point.normal, c.b == kWorldBody, s);
  }
}

}  // namespace cellphys::ppe
