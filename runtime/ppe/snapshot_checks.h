// What a snapshot's records must hold before a world is made of them (runtime/ppe/snapshot.cpp):
// the checksum catches damage on the way, these catch a snapshot that was written wrong or
// sealed again after editing. Each check throws WorldError naming the record, its index, the
// field and why, e.g. "snapshot: body 3: orientation is not a unit quaternion (norm 1.5)".
// They hold what the World's own API keeps true, so every snapshot it writes passes.
#pragma once
#include <cstdint>
#include <vector>

#include "runtime/ppe/body_records.h"
#include "runtime/ppe/contact_memory.h"
#include "runtime/ppe/shapes.h"
#include "runtime/ppe/step_sleep.h"

namespace cellphys::ppe {

/// Body i: its shape exists; scale, friction and damping in range; position, velocities and
/// sleep timer finite; a unit quaternion (within 1e-4); a static body at rest with no mass; a
/// dynamic one with a positive, finite mass, positive principal moments and the inverse of its
/// inertia (bit for bit what the World computes from it).
void check_snapshot_body(const ShapeDictionary& shapes, const WorldBody& b, uint32_t i);

/// Force i: a live force joins live bodies, body a dynamic, body b dynamic or the world as its
/// type allows, and every parameter finite and within its descriptor's bound.
void check_snapshot_force(const std::vector<WorldBody>& bodies, const WorldForce& f, uint32_t i);

/// A kept contact of sleeping group g: its bodies exist and its numbers are finite.
void check_snapshot_contact(const std::vector<WorldBody>& bodies, const WorldContact& c, uint32_t g, uint32_t k);

/// A contact memory pair: its bodies exist and its slip and anchors are finite.
void check_snapshot_pair(const std::vector<WorldBody>& bodies, uint64_t key, const ContactMemory::Pair& p);

/// The sleeping groups and the bodies agree: a group's members are live, dynamic, asleep, name
/// that group and are listed once; a body naming a group is in it; a free slot is empty and
/// listed once.
void check_snapshot_sleeping(const std::vector<WorldBody>& bodies, const SleepingGroups& s);

/// The event memory's touching pairs (low id, high id) or sensor overlaps (a sensor, a body
/// that is not one): sorted, each once, between live bodies.
void check_snapshot_event_pairs(const std::vector<WorldBody>& bodies, const std::vector<uint64_t>& keys, bool sensors,
                                const char* what);

}  // namespace cellphys::ppe
