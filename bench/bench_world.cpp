// One world step of the reference design's scenes, with the step's work (contacts, islands, active
// bodies, solver iterations, local store) and its stages (ppe::kStageTimeFields: broad, mid,
// narrow, wake, islands, decouple, pack, integrate, unpack, sleep; microseconds per step,
// averaged over the iterations) as counters, on 1 and 2 workers:
//  - the 65-box pile after 0.5 s of settling, all awake (the reference scene, 1 kg boxes;
//    and the same pile of 62.5 kg crates);
//  - the sparse 1,000-body world at its start (all awake) and after 10 s (most asleep).
//  - per-island cost by island size: N separate stacks of k boxes (k = 1, 2, 4, 8, 16, 65;
//    about 1,040 boxes in all), after 0.5 s, all awake; ns_per_island and ns_per_body;
//  - a step's fixed cost: one box at rest on the ground, awake;
//  - a step of the 100,000-body sparse world with every body asleep (built and settled once
//    per process, untimed, on the first run of BM_Sleeping100k), and the step that takes in
//    three boxes spawned into each other there.
// The awake cases restore the same state before every step (outside the timing), so every
// iteration times the same step; the 10 s case keeps stepping its mostly sleeping world.
// allocs_per_step counts the heap allocations made inside world.step() (this binary replaces
// operator new to count them, testing/count_allocations.h), after three untimed steps from the
// restored state: what a warm step allocates (nothing; tests/test_warm_steps.cpp asserts it).
#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <memory>
#include <string>
#include <vector>

#include "runtime/ppe/world.h"
#include "testing/count_allocations.h"
#include "testing/scenes.h"

namespace {

using namespace cellphys;
using namespace cellphys::testing;
using ppe::BodyState;
using ppe::StageTimeField;
using ppe::StageTimes;
using ppe::StepStats;
using ppe::kStageTimeFields;
using ppe::WorldSettings;

struct Snapshot {
  std::vector<BodyId> ids;
  std::vector<BodyState> states;
  void take(const World& w, const std::vector<BodyId>& bodies) {
    ids = bodies;
    states.clear();
    for (BodyId id : ids) states.push_back(w.state(id));
  }
  void restore(World& w) const {
    for (size_t k = 0; k < ids.size(); ++k) w.set_state(ids[k], states[k]);
  }
};

struct Sums {
  StageTimes stages;  // summed over the steps
  double contacts = 0, islands = 0, active = 0, iterations = 0, decoupled = 0, failed = 0, shared = 0, allocations = 0;
  size_t store = 0;
  // One step of w: its statistics and the heap allocations made inside it.
  void step(World& w) {
    const uint64_t before = allocation_count();
    add(w.step());
    allocations += double(allocation_count() - before);
  }
  void add(const StepStats& s) {
    for (const StageTimeField& f : kStageTimeFields) stages.*f.ms += s.times.*f.ms;
    contacts += s.contacts, islands += s.islands, active += s.active_bodies, iterations += s.solver_iterations;
    decoupled += s.decoupled_islands, failed += s.failed_islands, shared += s.shared_islands;
    store = std::max(store, s.local_store_peak_bytes);
  }
  void report(benchmark::State& state) const {
    using benchmark::Counter;
    const auto avg = Counter::kAvgIterations;
    // stage times in microseconds per step, by the stage's name (the whole step: step_us)
    for (const StageTimeField& f : kStageTimeFields) {
      const std::string name = f.ms == &StageTimes::total_ms ? "step" : f.name;
      state.counters[name + "_us"] = Counter(1e3 * (stages.*f.ms), avg);
    }
    state.counters["contacts"] = Counter(contacts, avg);
    state.counters["islands"] = Counter(islands, avg);
    state.counters["active"] = Counter(active, avg);
    state.counters["solver_its"] = Counter(iterations, avg);
    state.counters["decoupled"] = Counter(decoupled, avg);
    state.counters["failed"] = Counter(failed, avg);
    state.counters["shared"] = Counter(shared, avg);  // one-body islands stepped several to an image
    state.counters["store_peak_B"] = Counter(double(store));
    state.counters["allocs_per_step"] = Counter(allocations, avg);
  }
};

// Steps from `snap` a few times, untimed: the buffers a step needs grow in its first steps, so
// the timed ones (and their allocs_per_step) are a warm world's.
void warm_from(World& w, const Snapshot& snap) {
  for (int i = 0; i < 3; ++i) {
    snap.restore(w);
    w.step();
  }
}

// Times world.step() with the world restored to `snap` before each step.
void time_restored_steps(benchmark::State& state, World& w, const Snapshot& snap) {
  Sums sums;
  warm_from(w, snap);
  for (auto _ : state) {
    state.PauseTiming();
    snap.restore(w);
    state.ResumeTiming();
    sums.step(w);
  }
  sums.report(state);
  state.counters["max_speed"] = max_speed(w, snap.ids);  // after the timed step: a sanity flag
}

// args: box mass in tenths of a kg (10 = the reference design's 1 kg, 625 = a 62.5 kg crate), workers
void BM_Pile65Step(benchmark::State& state) {
  const float mass = float(state.range(0)) / 10.0f;
  WorldSettings s;
  s.workers = int(state.range(1));
  World w(s);
  const std::vector<BodyId> boxes = pile_in_bin(w, 65, 0.25f, 1, mass);
  for (int i = 0; i < 30; ++i) w.step();  // 0.5 s: landed, still awake (sleep needs 0.5 s of rest)
  Snapshot snap;
  snap.take(w, boxes);
  time_restored_steps(state, w, snap);
  state.SetLabel(std::string(mass == 1.0f ? "reference 1 kg boxes" : "crates") + ", after 0.5 s");
}
BENCHMARK(BM_Pile65Step)
    ->ArgNames({"mass_dg", "workers"})
    ->Args({10, 1})
    ->Args({10, 2})
    ->Args({625, 1})
    ->Args({625, 2})
    ->Unit(benchmark::kMicrosecond);

// A 4 x 4 x 4 block of mixed boxes spawned at 0.6 of their spacing (testing/scenes.h), awake
// throughout. arg 0: its first second, pushed apart and collapsing (each iteration spawns it
// afresh, untimed, then times 60 steps: the counters are per step); arg 1: the same block
// after 3 s, settled, one step an iteration. The two side by side are the spawn's cost.
void BM_SpawnedBlockStep(benchmark::State& state) {
  WorldSettings s;
  s.sleeping = false;
  const bool settled = state.range(0) == 1;
  Sums sums;
  if (settled) {
    World w(s);
    ground_plane(w);
    spawned_block(w, 4, 0.6f);
    for (int i = 0; i < 180; ++i) w.step();
    for (auto _ : state) sums.add(w.step());
    sums.report(state);
    state.SetLabel("settled, after 3 s");
    return;
  }
  constexpr int kSteps = 60;
  for (auto _ : state) {
    state.PauseTiming();
    World w(s);
    ground_plane(w);
    spawned_block(w, 4, 0.6f);
    state.ResumeTiming();
    for (int i = 0; i < kSteps; ++i) sums.add(w.step());
  }
  sums.report(state);
  for (auto& [name, counter] : state.counters) counter.value /= kSteps;  // per step, not per iteration
  state.SetLabel("the first second after spawning overlapping: counters per step, time per 60 steps");
}
BENCHMARK(BM_SpawnedBlockStep)->ArgName("settled")->Arg(0)->Arg(1)->Unit(benchmark::kMicrosecond);

// args: settle seconds before timing (0 = the first step, all awake), workers
void BM_Sparse1000Step(benchmark::State& state) {
  const int settle = int(state.range(0));
  WorldSettings s;
  s.workers = int(state.range(1));
  World w(s);
  const std::vector<BodyId> bodies = sparse_world(w, 1000, 100.0f, 1);
  if (settle == 0) {
    Snapshot snap;
    snap.take(w, bodies);
    time_restored_steps(state, w, snap);
    state.SetLabel("start, all awake");
    return;
  }
  for (int i = 0; i < settle * 60; ++i) w.step();
  Sums sums;
  for (auto _ : state) {
    sums.step(w);
  }
  sums.report(state);
  state.counters["asleep"] = count_asleep(w, bodies);
  state.SetLabel("after " + std::to_string(settle) + " s, mostly asleep");
}
BENCHMARK(BM_Sparse1000Step)
    ->ArgNames({"settle_s", "workers"})
    ->Args({0, 1})
    ->Args({0, 2})
    ->Args({10, 1})
    ->Args({10, 2})
    ->Unit(benchmark::kMicrosecond);

// Sleeping off, on `workers` threads: every body stays awake.
WorldSettings awake_settings(int workers) {
  WorldSettings s;
  s.sleeping = false;
  s.workers = workers;
  return s;
}

// A ground plane in w, and a 1 kg cube of half-extent h to place on it.
ppe::BodyDesc cube_on_ground(World& w, float h) {
  ground_plane(w);
  const float half[3] = {h, h, h};
  ppe::BodyDesc d;
  d.shape = w.shapes().add_box(half);
  d.mass = 1.0f;
  return d;
}

// World1000's kind of sparse world at its density with fewer bodies: a small room. Sleeping
// off, it steps 1 s (its bodies land), then every timed step steps on from the last: whether
// a second worker pays for so few bodies on this machine. args: bodies, workers
void BM_SparseWorldStep(benchmark::State& state) {
  const int n = int(state.range(0));
  World w(awake_settings(int(state.range(1))));
  sparse_world(w, n, 100.0f * std::sqrt(float(n) / 1000.0f), 1);
  for (int i = 0; i < 60; ++i) w.step();
  Sums sums;
  for (auto _ : state) sums.step(w);
  sums.report(state);
  state.SetLabel("after 1 s, awake (sleeping off), stepping on");
}
BENCHMARK(BM_SparseWorldStep)
    ->ArgNames({"bodies", "workers"})
    ->ArgsProduct({{100, 300}, {1, 2}})
    ->Unit(benchmark::kMicrosecond);

// Per-island cost by island size. arg 0: boxes per stack k; arg 1: workers. N = 1040 / k
// separate stacks of k 1 kg boxes (0.25 m half-extent, one dictionary box, each resting exactly
// on the one below) on a 2 m grid on the ground: N islands of k bodies, about 1,040 bodies in
// all. Timed after 0.5 s (landed, awake: sleeping is off), the state restored before every
// step. ns_per_island and ns_per_body: the step's wall time over N and over N k.
void BM_IslandSize(benchmark::State& state) {
  const int k = int(state.range(0));
  const int n = std::max(1, 1040 / k);
  World w(awake_settings(int(state.range(1))));
  const float h = 0.25f;
  ppe::BodyDesc d = cube_on_ground(w, h);
  const int side = int(std::ceil(std::sqrt(double(n))));
  std::vector<BodyId> bodies;
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < k; ++j) {
      d.state.position[0] = 2.0f * float(i % side - side / 2);
      d.state.position[1] = 2.0f * float(i / side - side / 2);
      d.state.position[2] = h + float(j) * 2 * h;
      bodies.push_back(w.add_body(d));
    }
  }
  for (int i = 0; i < 30; ++i) w.step();
  Snapshot snap;
  snap.take(w, bodies);
  warm_from(w, snap);
  Sums sums;
  double wall = 0;
  for (auto _ : state) {
    state.PauseTiming();
    snap.restore(w);
    state.ResumeTiming();
    const auto t0 = std::chrono::steady_clock::now();
    sums.step(w);
    wall += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  }
  sums.report(state);
  const double per_step_ns = 1e9 * wall / double(std::max<benchmark::IterationCount>(1, state.iterations()));
  state.counters["ns_per_island"] = per_step_ns / n;
  state.counters["ns_per_body"] = per_step_ns / (double(n) * k);
  state.counters["stacks"] = n;
  state.counters["max_speed"] = max_speed(w, bodies);
  state.SetLabel(std::to_string(n) + " stacks of " + std::to_string(k) + ", after 0.5 s");
}
BENCHMARK(BM_IslandSize)
    ->ArgNames({"k", "workers"})
    ->Args({1, 1})
    ->Args({2, 1})
    ->Args({4, 1})
    ->Args({8, 1})
    ->Args({16, 1})
    ->Args({65, 1})
    ->Args({1, 2})
    ->Args({65, 2})
    ->Unit(benchmark::kMicrosecond);

// A step's fixed cost: one box resting on the ground, sleeping off, stepped on and on (at rest it
// does the same work every step; a restore before each, as above, would cost more than the step).
// A game server stepping many small rooms pays this for each room every tick.
void BM_OneBodyStep(benchmark::State& state) {
  World w(awake_settings(1));
  const float h = 0.25f;
  ppe::BodyDesc d = cube_on_ground(w, h);
  d.state.position[2] = h;
  const BodyId box = w.add_body(d);
  for (int i = 0; i < 60; ++i) w.step();
  Sums sums;
  for (auto _ : state) sums.step(w);
  sums.report(state);
  state.counters["max_speed"] = max_speed(w, {box});
}
BENCHMARK(BM_OneBodyStep)->Unit(benchmark::kMicrosecond);

// The 100,000-body sparse world (sparse_world(w, 100000, 1000, 1): world1000's mix at the same
// density) stepped until every body sleeps (at most 60 simulated seconds), once per process
// and untimed; then a step of it, everything asleep. settle_s: the simulated seconds it took.
struct SleepingWorld {
  std::unique_ptr<World> world;
  std::vector<BodyId> bodies;
  double settle_s = 0, settle_wall_s = 0;
};

SleepingWorld& sleeping_world() {
  static SleepingWorld* sw = [] {
    auto* p = new SleepingWorld;  // kept to the end of the process
    p->world = std::make_unique<World>(WorldSettings{});
    p->bodies = sparse_world(*p->world, 100000, 1000.0f, 1);
    const auto t0 = std::chrono::steady_clock::now();
    int steps = 0;
    const int n = int(p->bodies.size());
    while (steps < 3600 && count_asleep(*p->world, p->bodies) < n) p->world->step(), ++steps;
    p->settle_s = steps / 60.0;
    p->settle_wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return p;
  }();
  return *sw;
}

void BM_Sleeping100k(benchmark::State& state) {
  SleepingWorld& sw = sleeping_world();
  World& w = *sw.world;
  Sums sums;
  for (auto _ : state) {
    sums.step(w);
  }
  sums.report(state);
  state.counters["bodies"] = double(sw.bodies.size());
  state.counters["asleep"] = count_asleep(w, sw.bodies);
  state.counters["settle_s"] = sw.settle_s;
  state.counters["settle_wall_s"] = sw.settle_wall_s;
  state.SetLabel("settled until every body sleeps, then stepped");
}
BENCHMARK(BM_Sleeping100k)->Unit(benchmark::kMicrosecond);

// A spawn into that world of sleepers: three 0.5 m boxes put into each other on open ground
// (untimed), the step that takes them in (collided, pushed apart, stepped), then removed again
// (untimed). A server spawning into a big world pays this: it should follow the three bodies.
void BM_SpawnIntoSleepers(benchmark::State& state) {
  SleepingWorld& sw = sleeping_world();
  World& w = *sw.world;
  const float h = 0.25f, half[3] = {h, h, h};
  static const uint32_t shape = w.shapes().add_box(half);
  const float at[3][3] = {{600.0f, 600.0f, h}, {600.0f + 1.6f * h, 600.0f, h}, {600.0f + 0.8f * h, 600.0f, 2.6f * h}};
  Sums sums;
  std::vector<BodyId> spawned;
  for (auto _ : state) {
    state.PauseTiming();
    spawned.clear();
    for (const auto& x : at) {
      ppe::BodyDesc d;
      d.shape = shape;
      d.mass = 1.0f;
      std::copy(x, x + 3, d.state.position);
      spawned.push_back(w.add_body(d));
    }
    state.ResumeTiming();
    sums.step(w);
    state.PauseTiming();
    for (BodyId id : spawned) w.remove_body(id);
    state.ResumeTiming();
  }
  sums.report(state);
  state.counters["bodies"] = double(sw.bodies.size() + spawned.size());
  state.counters["asleep"] = count_asleep(w, sw.bodies);
  state.SetLabel("three boxes spawned into each other, among 100,000 sleepers");
}
BENCHMARK(BM_SpawnIntoSleepers)->Unit(benchmark::kMicrosecond);

}  // namespace
