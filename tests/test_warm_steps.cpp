// A warm world steps without touching the heap: every buffer a step needs is the world's own
// and kept from one step to the next. Each scene is stepped from one saved state a few times
// (warming its buffers to the sizes that step needs), then from it again, counting the
// allocations made inside World::step on every thread: none may be left. This binary counts
// operator new itself, so it is a test executable of its own.
#include <gtest/gtest.h>

#include <functional>
#include <string>
#include <vector>

#include "runtime/ppe/world.h"
#include "testing/count_allocations.h"
#include "testing/scenes.h"

namespace {

using namespace cellphys;
using namespace cellphys::testing;
using ppe::BodyState;
using ppe::StepStats;
using ppe::World;
using ppe::WorldSettings;

constexpr int kWarmSteps = 3, kCountedSteps = 5;

struct Counted {
  uint64_t allocations = 0;
  StepStats last;
};

// Steps `w` from its present state kWarmSteps times, then kCountedSteps times more, the state
// put back before each step; the allocations of the counted steps.
Counted warm_allocations(World& w, const std::vector<BodyId>& bodies) {
  std::vector<BodyState> saved;
  for (BodyId id : bodies) saved.push_back(w.state(id));
  auto restore = [&] {
    for (size_t k = 0; k < bodies.size(); ++k) w.set_state(bodies[k], saved[k]);
  };
  Counted c;
  for (int i = 0; i < kWarmSteps + kCountedSteps; ++i) {
    restore();
    const uint64_t before = allocation_count();
    c.last = w.step();
    if (i >= kWarmSteps) c.allocations += allocation_count() - before;
  }
  return c;
}

// A scene: its bodies, set up in `w` and stepped `settle` steps before the count.
struct Scene {
  std::string name;
  std::function<std::vector<BodyId>(World&)> build;
  int settle = 30;
};

std::vector<Scene> scenes() {
  return {
      {"sparse_300", [](World& w) { return sparse_world(w, 300, 55.0f, 3); }},
      {"pile_65", [](World& w) { return pile_in_bin(w, 65, 0.25f, 1); }},
      {"block_64", [](World& w) {
         ground_plane(w);
         return spawned_block(w, 4, 0.95f);
       }},
      {"stack_12", [](World& w) {
         ground_plane(w);
         return stack(w, 12, 0.25f);
       }},
      {"chain_8", [](World& w) {
         ground_plane(w);
         return chain(w, 8);
       }, 10},
  };
}

// Whether each scene's warm steps allocate nothing; how many of them were decoupled.
int expect_no_warm_allocations(const WorldSettings& s, const char* what) {
  int decoupled = 0;
  for (const Scene& sc : scenes()) {
    World w(s);
    const std::vector<BodyId> bodies = sc.build(w);
    for (int i = 0; i < sc.settle; ++i) w.step();
    const Counted c = warm_allocations(w, bodies);
    EXPECT_GT(c.last.active_bodies, 0u) << sc.name << " (" << what << "): nothing awake, so nothing was stepped";
    EXPECT_EQ(c.last.failed_islands, 0u) << sc.name << " (" << what << ")";
    EXPECT_EQ(c.allocations, 0u) << sc.name << " (" << what << "): heap allocations in " << kCountedSteps
                                 << " warm steps";
    decoupled += c.last.decoupled_islands > 0;
  }
  return decoupled;
}

TEST(WarmStep, AllocatesNothingOnOneWorker) {
  WorldSettings s;
  s.sleeping = false;
  expect_no_warm_allocations(s, "1 worker");
}

TEST(WarmStep, AllocatesNothingOnTwoWorkers) {
  WorldSettings s;
  s.sleeping = false;
  s.workers = 2;
  expect_no_warm_allocations(s, "2 workers");
}

TEST(WarmStep, AllocatesNothingWhenIslandsAreDecoupled) {
  // a local store of 24 KiB cuts the block and the stack into parts every step and still holds
  // each part; the pile's columns of boxes land apart, each an island that fits whole
  WorldSettings s;
  s.sleeping = false;
  s.local_store_bytes = 24 * 1024;
  s.whole_island_bytes = 0;
  EXPECT_GE(expect_no_warm_allocations(s, "decoupled"), 2);
}

TEST(WarmStep, TheCountSeesAnAllocation) {
  // the counter this file relies on counts what the step's own code would allocate
  const uint64_t before = allocation_count();
  auto* v = new std::vector<int>(100);
  EXPECT_GE(allocation_count() - before, 2u);
  delete v;
}

}  // namespace
