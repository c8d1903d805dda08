// Stage 1 of the step: collision. Broad phase (bounding boxes grown by each body's reach in
// the step, culled against the simulated region), mid phase (sort and sweep, plus every
// awake body against every plane), narrow phase (contact manifolds of the pairs found).
#pragma once
#include <cstdint>
#include <utility>
#include <vector>

#include "runtime/ppe/body_records.h"
#include "runtime/ppe/box_tree.h"
#include "runtime/ppe/broad_phase.h"
#include "runtime/ppe/contact_loads.h"
#include "runtime/ppe/contact_memory.h"
#include "runtime/ppe/joint_groups.h"
#include "runtime/ppe/step_events.h"
#include "runtime/ppe/step_stats.h"
#include "runtime/ppe/worker_pool.h"

namespace cellphys::ppe {

struct WorldSettings;

/// The bodies a step visits and what changed since the last step's collision: the awake
/// bodies (ascending) and the ids of bodies that may have changed set, or moved while static,
/// since then (`changed`, may repeat); `all`: everything may have (a new or restored world,
/// changed settings).
struct BodyChanges {
  const std::vector<uint32_t>& awake;
  const std::vector<uint32_t>& changed;
  bool all;
};

/// One pair's manifold as the narrow phase finds it: a the dynamic body (or a sensor's
/// visitor), k points (k < 0: the pair is skipped, two sensors).
struct PairManifold {
  uint32_t a, b;
  int k;
  bool sensing;
  spu::ContactPoint cp[spu::kMaxManifoldPoints];
};

/// What collision keeps between steps (the sweep's order, the still boxes) and reuses (its
/// buffers). Per body slot, the box, reach and kind of a sleeping or static body are kept from
/// when it last changed; an awake body's are the step's.
struct CollideScratch {
  SweepAndPrune sap;
  BoxTree still;              // the boxes of sleeping and static bodies in the region
  std::vector<int32_t> leaf;  // per body: its leaf in `still`, or -1
  std::vector<uint8_t> outside;  // per body: a sleeping body outside the region
  uint32_t still_outside = 0;
  std::vector<Aabb> boxes;
  std::vector<float> reach;  // per body: distance it may close within the step (m)
  std::vector<BoxKind> kinds;
  std::vector<size_t> outside_of_task;  // awake boxes outside the region, per task of the threads
  std::vector<uint32_t> planes;  // ascending
  std::vector<uint32_t> woken;   // this step: the changed bodies awake now, ascending
  std::vector<PairManifold> manifolds;  // per pair, when the narrow phase runs on several threads
  std::vector<std::pair<uint32_t, uint32_t>> pairs, sorting;  // the boxes that overlap; the sort's buffer
  std::vector<uint64_t> joined;  // body pairs a joint joins (low id << 32 | high id), sorted
  std::vector<TouchedPair> touched;                   // the pairs with contacts, for the events
  std::vector<std::pair<uint32_t, uint32_t>> sensed;  // (sensor, visitor) overlapping
  LoadScratch loads;
  JointGroups groups;
};

/// The step's contact points in `contacts` (replaced): the dynamic body first, normals from a
/// to b, b = kWorldBody for static geometry, each with its mass and friction strain from the
/// pair's memory (then updated), and its hold (joint_groups.h). Two bodies a joint joins (a force whose descriptor says
/// `joint: true`) do not collide: a ragdoll's limbs overlap at their joints by design. A pair with
/// a sensor gives no contacts: it is in scratch.sensed while the two overlap. Times
/// broad, mid and narrow phase (with the recall). The narrow phase finds the pairs' manifolds
/// on the pool's threads when it has several (`pool` may be null), and takes them in pair order:
/// the same contacts on any number of threads.
void collide(const std::vector<WorldBody>& bodies, const std::vector<WorldForce>& forces, const ShapeDictionary& shapes,
             const WorldSettings& settings, const BodyChanges& changes, WorkerPool* pool, CollideScratch& scratch,
             ContactMemory& memory, std::vector<WorldContact>& contacts, StepStats& st);

}  // namespace cellphys::ppe
