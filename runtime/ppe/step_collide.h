// Stage 1 of the step: collision. Broad phase (bounding boxes grown by each body's reach in
// the step, culled against the simulated region), mid phase (sort and sweep, plus every
// awake body against every plane), narrow phase (contact manifolds of the pairs found).
#pragma once
#include <cstdint>
#include <utility>
#include <vector>

#include "runtime/ppe/body_records.h"
#include "runtime/ppe/broad_phase.h"
#include "runtime/ppe/contact_loads.h"
#include "runtime/ppe/contact_memory.h"
#include "runtime/ppe/step_events.h"
#include "runtime/ppe/step_stats.h"

namespace cellphys::ppe {

struct WorldSettings;

/// What collision keeps between steps (the sweep's order) and reuses (its buffers).
struct CollideScratch {
  SweepAndPrune sap;
  std::vector<Aabb> boxes;
  std::vector<float> reach;  // per body: distance it may close within the step (m)
  std::vector<BoxKind> kinds;
  std::vector<uint32_t> planes;
  std::vector<std::pair<uint32_t, uint32_t>> pairs;
  std::vector<uint64_t> joined;  // body pairs a joint joins (low id << 32 | high id), sorted
  std::vector<TouchedPair> touched;                   // the pairs with contacts, for the events
  std::vector<std::pair<uint32_t, uint32_t>> sensed;  // (sensor, visitor) overlapping
  LoadScratch loads;
};

/// The step's contact points in `contacts` (replaced): the dynamic body first, normals from a
/// to b, b = kWorldBody for static geometry, each with its mass and friction strain from the
/// pair's memory (then updated). Two bodies a joint joins (a force whose descriptor says
/// `joint: true`) do not collide: a ragdoll's limbs overlap at their joints by design. A pair with
/// a sensor gives no contacts: it is in scratch.sensed while the two overlap. Times
/// broad, mid and narrow phase (with the recall).
void collide(const std::vector<WorldBody>& bodies, const std::vector<WorldForce>& forces, const ShapeDictionary& shapes,
             const WorldSettings& settings, CollideScratch& scratch, ContactMemory& memory,
             std::vector<WorldContact>& contacts, StepStats& st);

}  // namespace cellphys::ppe
