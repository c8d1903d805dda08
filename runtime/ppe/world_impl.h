// The world's private state, shared by world.cpp (the step) and snapshot.cpp (save and
// restore): everything a step reads that is not in WorldSettings or the shape dictionary.
#pragma once
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "runtime/ppe/body_records.h"
#include "runtime/ppe/body_sets.h"
#include "runtime/ppe/query_tree.h"
#include "runtime/ppe/step_collide.h"
#include "runtime/ppe/step_events.h"
#include "runtime/ppe/step_integrate.h"
#include "runtime/ppe/step_islands.h"
#include "runtime/ppe/step_push.h"
#include "runtime/ppe/step_sleep.h"
#include "runtime/ppe/world.h"
#include "runtime/ppe/worker_pool.h"

namespace cellphys::ppe {

inline std::string body_name(BodyId id) { return "body " + std::to_string(id); }

/// The couplings the decoupling stage cut, into `out` (replaced): those in more than one part of
/// an island, by island, contacts then forces, each by id (runtime/ppe/world_debug.cpp; for
/// display). `ids` is scratch: a warm step allocates nothing.
void cut_couplings_of(const DecoupledIslands& d, const std::vector<WorldContact>& contacts,
                      const std::vector<WorldForce>& forces, std::vector<uint32_t>& ids, std::vector<CutCoupling>& out);

struct World::Impl {
  std::vector<WorldBody> bodies;
  std::vector<WorldForce> forces;
  SleepingGroups sleeping;
  AwakeBodies awake;                    // the awake dynamic bodies, kept from sleeping.changed
  std::vector<uint32_t> step_changed;   // what sleeping.changed held at the step's start
  std::unique_ptr<WorkerPool> pool;
  int pool_workers = 0;
  size_t pool_bytes = 0, pool_whole_bytes = 0;
  std::shared_ptr<IslandRunner> runner;   // set_runner(); the pool when null
  std::unique_ptr<spu::ComputeWorker> local;  // recomputes islands whose result came back unsound
  CollideScratch collide;               // the sweep's order, kept between steps; buffers
  ContactMemory contact_memory;         // friction anchors and contact masses, kept between steps
  std::vector<WorldContact> contacts;   // this step's, reused
  PushScratch push;                     // the push stage's buffers
  IslandScratch island_scratch;
  std::vector<IslandContent> islands;   // this step's islands, their storage reused
  DecoupledIslands parts;               // and their parts
  IntegrateScratch integrate;           // packing and running islands: buffers
  std::vector<uint8_t> failed;          // per island: its step failed
  std::vector<uint32_t> island_of;      // per body slot: its island in the last step (for display only)
  std::vector<uint32_t> island_listed;  // the bodies island_of gives an island
  std::vector<uint8_t> island_decoupled;  // per island of the last step: cut in parts
  std::vector<CutCoupling> cut;           // the last step's cut couplings (for display only)
  std::vector<uint32_t> cut_ids;          // their finding's scratch
  EventMemory event_memory;               // touching pairs and sensor overlaps, kept between steps
  PendingEvents pending_events;           // a step's begun touches (its storage kept)
  std::vector<ContactEvent> contact_events;  // the last step's
  std::vector<SensorEvent> sensor_events;    // the last step's
  uint64_t revision = 0;                  // counts changes to the bodies' set or poses
  mutable QueryIndex queries;             // the queries' tree, brought up to date by the first query after a change

  WorkerPool& workers(const WorldSettings& s) {
    if (!pool || pool_workers != s.workers || pool_bytes != s.local_store_bytes || pool_whole_bytes != s.whole_island_bytes) {
      pool.reset();
      pool = std::make_unique<WorkerPool>(s.workers, s.local_store_bytes, s.whole_island_bytes);
      pool_workers = s.workers;
      pool_bytes = s.local_store_bytes;
      pool_whole_bytes = s.whole_island_bytes;
    }
    return *pool;
  }
  IslandRunner& islands_runner(const WorldSettings& s) { return runner ? *runner : workers(s); }
  spu::ComputeWorker& local_worker(const WorldSettings& s) {
    if (!local || local->local_store().capacity() != s.local_store_bytes)
      local = std::make_unique<spu::ComputeWorker>(s.local_store_bytes);
    return *local;
  }
  // Where the step computes islands; each part is made on first use.
  IslandCompute compute(const WorldSettings& s) {
    return {[this, &s]() -> IslandRunner& { return islands_runner(s); },
            [this, &s]() -> spu::ComputeWorker& { return local_worker(s); }, &workers(s)};
  }
  WorldBody& live(BodyId id) {
    if (id >= bodies.size() || !bodies[id].alive) throw WorldError(body_name(id) + " does not exist");
    return bodies[id];
  }
  const WorldBody& live(BodyId id) const {
    if (id >= bodies.size() || !bodies[id].alive) throw WorldError(body_name(id) + " does not exist");
    return bodies[id];
  }
  void wake(BodyId id) { wake_body(bodies, sleeping, id); }
  // Body `id` was added or removed, or its state was set: the step files it again.
  void changed(BodyId id) { sleeping.changed.push_back(id); }
};

}  // namespace cellphys::ppe
