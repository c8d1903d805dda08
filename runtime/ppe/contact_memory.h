// What a body pair's contact points keep from one step to the next: the friction anchors
// where they stuck (docs/contacts.md).
#pragma once
#include <cstdint>
#include <utility>
#include <vector>

#include "runtime/ppe/body_records.h"
#include "runtime/ppe/dormant_pairs.h"
#include "runtime/ppe/pair_table.h"
#include "runtime/spu/shape.h"

namespace cellphys::ppe {

class WorkerPool;

struct WorldSettings;

struct ContactMemory {
  /// A friction anchor: the material points of a and b that stuck together (body frames; the
  /// world's in the world frame).
  struct Anchor {
    float on_a[3], on_b[3];
  };
  /// A touching pair: whether it slid in the step, its fastest slip then (m/s), its anchors.
  struct Pair {
    uint64_t seen = 0;  // the recall that last found it touching
    uint32_t sliding = 0;
    float slip = 0.0f;
    float drift[3] = {};  // the mean tangential velocity of b against a over its points (world)
    uint32_t count = 0;
    // Bit i: point i was a gap its bodies ended the last step neither closing within a step nor
    // approaching faster than contact.rest_speed (note_held_gaps): something held them apart.
    uint32_t held_gaps = 0;
    Anchor anchors[spu::kMaxManifoldPoints];
  };
  PairTable<Pair> pairs;  // by pair_key(a, b)
  uint64_t step = 0;                          // recalls so far
  // Which pairs a recall may forget: those it found (`active`), and those of bodies that woke,
  // taken back from `dormant`, where the pairs of two sleeping (or static) bodies wait.
  std::vector<uint64_t> active;
  DormantPairs dormant;
  std::vector<uint64_t> review, resting;  // buffers
  std::vector<std::pair<uint64_t, uint32_t>> held;  // note_held_gaps' buffer: a pair's key and held gaps
  // recall_contacts' buffer: a pair's contacts [first, end), its entry (or null) and its memory now
  struct Span {
    size_t first, end;
    Pair* found;
    Pair now;
  };
  std::vector<Span> spans;
};

inline uint64_t pair_key(uint32_t a, uint32_t b) { return (uint64_t(a) << 32) | b; }

/// Gives each of this step's contacts (grouped by pair, as collide() writes them) its
/// effective mass along the normal and its friction strain and mode from the pair's memory,
/// and makes this step's the memory. Pairs
/// of sleeping bodies are remembered as they were; pairs no longer touching are forgotten.
/// `woken` (ascending): the bodies awake now that slept at the last recall, or may have;
/// `all`: every pair may have changed (a restored world).
/// `pool` (may be null): the threads that recall pairs at once; the result is the same without.
void recall_contacts(const std::vector<WorldBody>& bodies, const WorldSettings& s, const std::vector<uint32_t>& woken,
                     bool all, WorkerPool* pool, ContactMemory& memory, std::vector<WorldContact>& contacts);

/// After the step: which of each pair's gaps its bodies left open, approaching slower than the
/// gap over a step and than contact.rest_speed (or opening). Gravity is not taken to close such a gap in the next step
/// (its `fall` is 0 there): what held the bodies apart holds them still, and a landing damper
/// that took gravity's fall pulled them together instead: a ragdoll whose pelvis and head hovered
/// half a millimetre above the ground, held by their joints, was pulled down every step (it sank
/// at 2 cm/s), pressed its other parts past their hold, and was pushed back up for ever.
void note_held_gaps(const std::vector<WorldBody>& bodies, const WorldSettings& s,
                    const std::vector<WorldContact>& contacts, ContactMemory& memory);

/// The push stage moved a by `da` and b by `db` (world frame): the pair's anchors follow the
/// middle of the two, as its points do, so that moving bodies out of overlap strains no friction.
void move_anchors(const std::vector<WorldBody>& bodies, ContactMemory& memory, uint32_t a, uint32_t b,
                  const float da[3], const float db[3]);

/// Forgets every pair with body `id` (removed: its id may be given to a new body).
void forget_body(ContactMemory& memory, uint32_t id);

}  // namespace cellphys::ppe
