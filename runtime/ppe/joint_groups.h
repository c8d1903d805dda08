// Which dynamic bodies joints join into one group, directly or through other dynamic bodies (a
// ragdoll's forearm and its chest), and so how each contact between two of them acts. The push
// stage (runtime/ppe/step_push.h) moves such a group as one, so it cannot push two of its bodies
// apart: their overlap is their contact spring's alone, and that spring acts deeper than one the
// push stage backs (settings.contact_joined_hold_depth against globals.contact_hold_depth). And
// gravity is not taken to close a gap between them: it pulls both alike while their joints hold
// them (taken to, a gap's landing damper pulled a resting ragdoll's parts together with up to
// 2 kN, and it rocked for ever).
#pragma once
#include <cstdint>
#include <vector>

#include "runtime/ppe/body_records.h"
#include "runtime/ppe/settings.h"

namespace cellphys::ppe {

class JointGroups {
 public:
  /// Groups the bodies by the live joints (forces whose descriptor says `joint: true`) between
  /// two dynamic bodies; a joint to the world or a static body joins nothing.
  void build(const std::vector<WorldBody>& bodies, const std::vector<WorldForce>& forces);
  bool joined(uint32_t a, uint32_t b) const {
    return !root_.empty() && a < root_.size() && b < root_.size() && root_[a] == root_[b];
  }

  bool empty() const { return root_.empty(); }

 private:
  std::vector<uint32_t> root_;  // per body: its group's lowest id; empty when no joint joins two bodies
};

/// Sets each contact's hold and fall: between two bodies of one group, settings.
/// contact_joined_hold_depth and no fall; otherwise globals.contact_hold_depth and gravity_fall.
void set_contact_hold_and_fall(const WorldSettings& s, const JointGroups& groups, std::vector<WorldContact>& contacts);

/// Tunes each contact between two bodies of one group to at least the heavier body's own mass
/// along its normal at its point (its load), whatever weight it carries. The light body is
/// backed by what holds it (a forearm by the ground under it), so the pair's effective mass
/// understates what lands on it: tuned to that, a 1.9 m ragdoll's torso landing on its own
/// forearm at 4.4 m/s was found 4.2 cm into it and sank to 9.4 cm over the next two steps, deeper
/// than its 1 cm spring or its joints' limits could bring back. Contacts outside groups need no
/// floor: the push stage backs them.
void load_joined_contacts(const std::vector<WorldBody>& bodies, const JointGroups& groups,
                          std::vector<WorldContact>& contacts);

}  // namespace cellphys::ppe
