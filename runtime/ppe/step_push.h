// Stage 3 of the step: overlap deeper than a contact's hold (bodies spawned or teleported
// into each other) is moved out before the islands are built, by moving the awake bodies apart
// along the contact normals; velocities are untouched, so a pile spawned into itself unfolds
// without being thrown. (Box2D's soft step separates with a bias velocity its relax pass then
// removes; Bullet's split impulse moves positions apart the same way.) The contact spring acts
// on its hold only (contact_hold_depth; deeper between bodies joints join, joint_groups.h).
// Done here, on the whole connected pile, rather than per island in the kernel: a decoupled
// part cannot move its ghosts, and a column must lift as one.
#pragma once
#include <cstdint>
#include <vector>

#include "runtime/ppe/body_records.h"
#include "runtime/ppe/step_stats.h"

namespace cellphys::ppe {

struct WorldSettings;
struct ContactMemory;

/// Reusable buffers of the push stage.
struct PushScratch {
  std::vector<uint32_t> slot;             // per body of the world: its number below, or none
  std::vector<uint32_t> ids;              // per number: the body (the movable ones contacts and joints name)
  // per number:
  std::vector<uint32_t> first, adjacent;  // its contacts (CSR)
  std::vector<uint32_t> link_first, linked;  // the numbers joints join it to (CSR)
  std::vector<uint32_t> group;            // the number of the lowest body joints join it to
  std::vector<int32_t> level;             // contacts away from what cannot move
  std::vector<double> moved;              // at a group's number: its displacement (xyz)
  std::vector<double> group_mass;         // at a group's number: its bodies' mass
  std::vector<uint8_t> pinned, seen;     // jointed to what cannot move; in a pile found
  std::vector<uint32_t> roots, queue, members, order;
  std::vector<float> target;              // per contact of `order`: the separation it asks for
  std::vector<size_t> bucket_start;      // the contacts' order: where each level begins
  std::vector<uint32_t> place;           // per contact: its place in that order
  std::vector<uint8_t> due;              // per place: to be visited in the sweep
};

/// Stage 3: each contact deeper than the hold depth asks to separate by its excess, at most
/// contact_push_speed x dt in a step, relative to its two bodies (so what rests on a body is
/// carried with it); the bodies of the piles holding such a contact are moved to meet every
/// request at once (projected Gauss-Seidel on positions, lowest contacts first). A contact within
/// 60 degrees of vertical moves only its upper body, so a box is lifted off its support and never
/// pressed into it; flatter ones share by inverse mass; the world and static and sleeping bodies
/// do not move. Bodies a joint joins (a `joint: true` force) move as one: the push is a
/// translation, so a joint's points keep their gap; a body jointed to the world or to what cannot
/// move is not pushed. The contacts' depths and points follow the moved bodies, and their friction
/// anchors (`memory`) too: a push is no strain. Counts the moved bodies.
void push_out_overlaps(const WorldSettings& s, const std::vector<WorldForce>& forces, std::vector<WorldBody>& bodies,
                       std::vector<WorldContact>& contacts, ContactMemory& memory, PushScratch& scratch, StepStats& st);

}  // namespace cellphys::ppe
