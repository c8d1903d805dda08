#include "runtime/ppe/joint_groups.h"

#include <algorithm>

#include "cellphys/gen/force_table.h"
#include "runtime/base/mat3.h"
#include "runtime/base/quat.h"
#include "runtime/ppe/body_maths.h"
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

void load_joined_contacts(const std::vector<WorldBody>& bodies, const JointGroups& groups,
                          std::vector<WorldContact>& contacts) {
  if (groups.empty()) return;
  auto own_mass = [&](uint32_t id, const Vec3d& p, const Vec3d& n) {
    const WorldBody& b = bodies[id];
    const Mat3d Iinv = rotate_sym(quat_to_matrix(Quatd::load(b.state.orientation)), b.inverse_inertia);
    return 1.0 / inverse_mass_along(1.0 / b.mass, Iinv, Vec3d::load(b.state.position), p, n);
  };
  for (WorldContact& c : contacts) {
    if (!groups.joined(c.a, c.b)) continue;
    const Vec3d p = Vec3d::load(c.point.point), n = Vec3d::load(c.point.normal);
    c.load = float(std::max({double(c.load), own_mass(c.a, p, n), own_mass(c.b, p, n)}));
  }
}

}  // namespace cellphys::ppe
