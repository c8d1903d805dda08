// Stage 8 of the step: events. Which body pairs began and ended touching in the step, with the
// touch's speed and impulse (sounds, damage), and which bodies entered and left each sensor
// (triggers). Decided from what collision found (docs/events.md).
#pragma once
#include <cstdint>
#include <vector>

#include "runtime/ppe/body_records.h"
#include "runtime/ppe/dormant_pairs.h"
#include "runtime/ppe/world.h"

namespace cellphys::ppe {

/// What the events stage keeps from one step to the next (and a snapshot carries): the pairs
/// touching and the sensor overlaps at the end of the last step, and the ends that bodies
/// removed since then owe to the next step's events.
struct EventMemory {
  std::vector<uint64_t> touching;  // low id << 32 | high id, sorted; with a body that may move
  DormantPairs resting;            // the touching pairs of bodies that both sleep or are static
  std::vector<uint64_t> sensing;   // sensor << 32 | visitor, sorted
  std::vector<ContactEvent> removed_touches;
  std::vector<SensorEvent> removed_overlaps;
  std::vector<uint64_t> found, back, resting_now;  // the stage's buffers (not kept: a snapshot leaves them out)
};

/// A pair of bodies collision found this step: `contacts[first, first + count)` are its points
/// (b is the static body's own id here, where the contacts say kWorldBody).
struct TouchedPair {
  uint32_t a, b;
  uint32_t first, count;
};

/// The pairs that may begin touching this step (collided, not touching before), measured before
/// the step moves anything; their impulse waits for the step.
struct PendingEvents {
  struct Candidate {
    ContactEvent begin;        // a, b, the middle of the points, their normal, the approach speed
    float mass;                // effective mass along the normal at the middle (kg)
    float free_speed;          // separating speed there if only gravity acted (m/s)
    bool acts;                 // a point overlaps, or closes its gap within the step at its speed
  };
  std::vector<ContactEvent> events;  // the ends
  std::vector<Candidate> candidates;
};

/// Compares this step's pairs (`touched`, with their contacts, and the sensor overlaps
/// `sensed`, sensor first) with the memory: the ends and the sensor events are final, the
/// begins are candidates. A touching pair the step did not collide stays touching while both
/// bodies sleep or are static, or while it still closes: within twice the margin collision used
/// (`reach`: each body's in the step), a point of it closing, as a fast body braked short of what
/// it falls on is. `woken` (ascending): the bodies awake now that may have slept at the last
/// step; `all`: any may have (a restored world). Into `out` and `sensor_events` (replaced; their
/// storage, and the memory's, is kept: a warm step allocates nothing).
void begin_events(const std::vector<WorldBody>& bodies, const ShapeDictionary& shapes, const WorldSettings& s,
                  const std::vector<uint32_t>& woken, bool all, const std::vector<float>& reach,
                  const std::vector<WorldContact>& contacts, const std::vector<TouchedPair>& touched,
                  const std::vector<std::pair<uint32_t, uint32_t>>& sensed, EventMemory& memory,
                  std::vector<SensorEvent>& sensor_events, PendingEvents& out);

/// The candidates whose contact acts in the step (the descriptor's: a point that overlaps or
/// closes within the step, gravity's fall counted) begin touching, with their impulse from the
/// bodies' velocities after the step.
void finish_events(const std::vector<WorldBody>& bodies, PendingEvents& pending,
                   EventMemory& memory, std::vector<ContactEvent>& events);

/// Body `id` is removed: its touches and overlaps end, reported by the next step.
void end_events_of(EventMemory& memory, uint32_t id);

/// Every touching pair, ascending (what a snapshot keeps).
std::vector<uint64_t> touching_pairs(const EventMemory& memory);

}  // namespace cellphys::ppe
