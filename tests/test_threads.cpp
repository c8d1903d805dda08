// Worlds and worker pools on several threads: what a server running one world per room, each
// with its own pool, relies on. Built and run under ThreadSanitizer by scripts/test (the tsan
// preset) as well as in the ordinary passes (label "threads").
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstring>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "runtime/ppe/island_runner.h"
#include "runtime/ppe/worker_pool.h"
#include "runtime/ppe/world.h"
#include "runtime/scene/scene.h"
#include "runtime/spu/kernel.h"
#include "testing/scenes.h"
#include "tests/support/backward_sharer.h"

namespace {

using cellphys::ppe::World;

std::unique_ptr<World> scene_world(const std::string& name, int workers) {
  auto built = cellphys::scene::build_world(cellphys::scene::load_scene(std::string(CELLPHYS_SCENES_DIR) + "/" + name + ".json"));
  auto s = built.world->settings();
  s.workers = workers;
  built.world->set_settings(s);
  return std::move(built.world);
}

struct SceneRun {
  const char* scene;
  int steps;
};

uint64_t run_alone(const SceneRun& r, int workers) {
  auto w = scene_world(r.scene, workers);
  for (int s = 0; s < r.steps; ++s) w->step();
  return w->state_hash();
}

// Four independent worlds, each with a pool of two workers, stepped at once on four threads:
// each ends on the hash it ends on alone. Nothing in the runtime is shared between worlds
// but what is read-only (the force table, the settings table, the shape types).
TEST(Threads, FourWorldsOnFourThreadsEndAsAlone) {
  const SceneRun runs[4] = {{"world1000", 20}, {"pile65", 45}, {"chain_ratio", 60}, {"newton_cradle", 60}};
  uint64_t alone[4], together[4] = {};
  for (int k = 0; k < 4; ++k) alone[k] = run_alone(runs[k], 2);
  std::vector<std::thread> threads;
  for (int k = 0; k < 4; ++k) threads.emplace_back([&, k] { together[k] = run_alone(runs[k], 2); });
  for (std::thread& t : threads) t.join();
  for (int k = 0; k < 4; ++k) EXPECT_EQ(together[k], alone[k]) << runs[k].scene;
  EXPECT_EQ(run_alone(runs[1], 1), alone[1]) << "two workers give one worker's bits";
}

// A runner that keeps a copy of every job of the first wave it sees, and computes them in turn.
class Capture : public cellphys::ppe::IslandRunner {
 public:
  std::vector<std::vector<unsigned char>> images;
  void set_local_store(size_t bytes) override { bytes_ = bytes; }
  void run(const std::vector<cellphys::spu::IslandJob>& jobs, std::vector<cellphys::spu::IslandReport>& reports) override {
    if (images.empty())
      for (const auto& j : jobs) images.emplace_back(j.image, j.image + j.bytes);
    cellphys::spu::ComputeWorker worker(bytes_);
    reports.clear();
    for (const auto& j : jobs) reports.push_back(worker.step(j.image, j.bytes, j.result, j.result_capacity));
  }
  const char* name() const override { return "capture"; }
  size_t bytes_ = cellphys::spu::LocalStore::kDefaultCapacity;
};

// The number of bodies in a packed island.
uint32_t bodies_of(const std::vector<unsigned char>& image) {
  cellphys::gen::Island_Header h;
  std::memcpy(&h, image.data(), sizeof h);
  return h.num_bodies;
}

// The pool directly: world1000's first wave (hundreds of islands, largest first) run twenty
// times by a pool of three (the calling thread and two of its own) gives, byte for byte, what
// one compute worker gives, every time.
TEST(Threads, WorkerPoolGivesOneWorkersResultsWaveAfterWave) {
  auto w = scene_world("world1000", 1);
  auto capture = std::make_shared<Capture>();
  w->set_runner(capture);
  w->step();
  const auto& images = capture->images;
  ASSERT_GT(images.size(), 100u);
  const size_t ls = w->settings().local_store_bytes;
  auto run = [&](cellphys::ppe::IslandRunner& runner, std::vector<std::vector<unsigned char>>& results,
                 std::vector<cellphys::spu::IslandReport>& reports) {
    results.clear();
    std::vector<cellphys::spu::IslandJob> jobs;
    for (const auto& img : images) results.emplace_back(cellphys::spu::result_bytes(bodies_of(img)));
    for (size_t k = 0; k < images.size(); ++k)
      jobs.push_back({images[k].data(), images[k].size(), results[k].data(), results[k].size()});
    runner.run(jobs, reports);
  };
  Capture one;
  one.set_local_store(ls);
  std::vector<std::vector<unsigned char>> expected, got;
  std::vector<cellphys::spu::IslandReport> expected_reports, reports;
  run(one, expected, expected_reports);
  cellphys::ppe::WorkerPool pool(3, ls);
  ASSERT_EQ(pool.size(), 3);
  for (int wave = 0; wave < 20; ++wave) {
    run(pool, got, reports);
    ASSERT_EQ(reports.size(), expected_reports.size());
    for (size_t k = 0; k < images.size(); ++k) {
      ASSERT_EQ(reports[k].status, expected_reports[k].status) << "wave " << wave << ", island " << k;
      ASSERT_EQ(got[k], expected[k]) << "wave " << wave << ", island " << k;
    }
  }
}

// for_ranges gives every item to exactly one range, whatever the grain, with the threads held
// spinning (nested holds too) and after the holds end and they sleep again.
TEST(Threads, PoolRangesCoverEveryItemOnceHeldOrNot) {
  cellphys::ppe::WorkerPool pool(3, 64 * 1024);
  auto check = [&](size_t count, size_t grain) {
    std::vector<int> seen(count, 0);
    std::vector<int> threads(count, -1);
    pool.for_ranges(count, grain, [&](size_t begin, size_t end, int thread) {
      ASSERT_LT(begin, end);
      ASSERT_LE(end, count);
      ASSERT_LE(end - begin, grain ? grain : 1);
      for (size_t i = begin; i < end; ++i) ++seen[i], threads[i] = thread;
    });
    for (size_t i = 0; i < count; ++i) {
      ASSERT_EQ(seen[i], 1) << "item " << i << " of " << count << ", grain " << grain;
      ASSERT_GE(threads[i], 0);
      ASSERT_LT(threads[i], pool.size());
    }
  };
  for (int round = 0; round < 3; ++round) {
    {
      cellphys::ppe::WorkerPool::Hold hold(pool);
      cellphys::ppe::WorkerPool::Hold again(pool);
      for (size_t count : {0, 1, 7, 64, 1000})
        for (size_t grain : {0, 1, 3, 32, 5000}) check(count, grain);
    }
    std::this_thread::sleep_for(std::chrono::microseconds(200));  // past the spin: asleep
    check(999, 16);
  }
}

// A kernel's shared loop (share(), what a big island's products use): held, a waiting thread
// takes ranges of it while the caller runs the rest; every item runs once, held or not, with
// one thread or several, and each range is the grain or the tail.
TEST(Threads, PoolSharesAKernelsLoopWithAWaitingThread) {
  struct Loop {
    std::vector<std::atomic<int>> seen;
    std::mutex m;
    std::vector<std::thread::id> threads;
    size_t grain;
    explicit Loop(size_t count, size_t g) : seen(count), grain(g) {}
    size_t distinct() {
      std::lock_guard<std::mutex> lock(m);
      return threads.size();
    }
  };
  auto run = [](cellphys::ppe::WorkerPool& pool, size_t count, size_t grain, bool wait_for_help) {
    Loop loop(count, grain);
    struct Context {
      Loop* loop;
      bool wait;
    } context{&loop, wait_for_help};
    pool.share(count, grain, [](void* c, size_t begin, size_t end) {
      Context& ctx = *static_cast<Context*>(c);
      Loop& l = *ctx.loop;
      EXPECT_LT(begin, end);
      EXPECT_TRUE(end - begin == l.grain || end == l.seen.size()) << begin << ".." << end;
      {
        std::lock_guard<std::mutex> lock(l.m);
        if (std::find(l.threads.begin(), l.threads.end(), std::this_thread::get_id()) == l.threads.end())
          l.threads.push_back(std::this_thread::get_id());
      }
      for (size_t i = begin; i < end; ++i) l.seen[i].fetch_add(1);
      // The first range waits (up to 20 s, for a loaded machine) until a second thread has run
      // one: whoever took it, the other is still there to take the rest.
      if (ctx.wait && begin == 0)
        for (auto t0 = std::chrono::steady_clock::now();
             l.distinct() < 2 && std::chrono::steady_clock::now() - t0 < std::chrono::seconds(20);)
          std::this_thread::yield();
    }, &context);
    for (size_t i = 0; i < count; ++i) EXPECT_EQ(loop.seen[i].load(), 1) << "item " << i << " of " << count;
    return loop.distinct();
  };
  cellphys::ppe::WorkerPool pool(2, 64 * 1024), one(1, 64 * 1024);
  {
    cellphys::ppe::WorkerPool::Hold hold(pool);
    EXPECT_EQ(run(pool, 1000, 10, true), 2u) << "the waiting thread took no range";
    for (size_t count : {0, 1, 5, 999}) run(pool, count, 7, false);
    cellphys::ppe::WorkerPool::Hold alone(pool, false);
    EXPECT_EQ(run(pool, 500, 10, false), 1u) << "held without threads, the caller runs it all";
  }
  std::this_thread::sleep_for(std::chrono::microseconds(200));  // past the spin: asleep
  run(pool, 999, 16, false);
  EXPECT_EQ(run(one, 300, 10, false), 1u);
}

// Held without threads (a step with no awake body), every item runs on the calling thread;
// once that hold ends, the threads take items again, the enclosing hold's mode restored.
TEST(Threads, PoolHeldWithoutThreadsRunsOnTheCaller) {
  cellphys::ppe::WorkerPool pool(3, 64 * 1024);
  cellphys::ppe::WorkerPool::Hold held(pool);
  {
    cellphys::ppe::WorkerPool::Hold alone(pool, /*threads=*/false);
    std::vector<int> threads(200, -1);
    pool.for_each(threads.size(), [&](size_t k, int thread) {  // items long enough to share
      threads[k] = thread;
      const auto start = std::chrono::steady_clock::now();
      while (std::chrono::steady_clock::now() - start < std::chrono::microseconds(20)) {
      }
    });
    for (size_t k = 0; k < threads.size(); ++k) ASSERT_EQ(threads[k], 0) << "item " << k;
  }
  // Each item waits (up to 10 s) for an item to run on another thread: only a pool that
  // shares its items again gets through without the wait.
  std::atomic<int> others{0};
  std::atomic<bool> timed_out{false};
  pool.for_each(64, [&](size_t, int thread) {
    if (thread != 0) ++others;
    const auto start = std::chrono::steady_clock::now();
    while (others.load() == 0 && !timed_out.load())
      if (std::chrono::steady_clock::now() - start > std::chrono::seconds(10)) timed_out = true;
  });
  EXPECT_FALSE(timed_out.load());
  EXPECT_GT(others.load(), 0);
}

// A runner that keeps the first wave's images whole (an island over the local store is sent
// as it is, not decoupled) and computes each on a worker with the store it needs.
class CaptureWhole : public Capture {
 public:
  size_t whole_island_bytes() const override { return cellphys::spu::LocalStore::kMaxCapacity; }
};

// One island of 820 boxes (a one-layer pyramid, 40 at its base), too big for the local store
// and with enough blocks that its products are shared out: run by a held pool of three on a
// thread's wide worker, wave after wave, and by a worker whose sharer runs the ranges
// backwards, it comes back byte for byte as one worker with the store it needs computes it alone.
TEST(Threads, ABigIslandOnAPoolGivesOneWorkersBytes) {
  World w;
  cellphys::testing::ground_plane(w);
  const float half[3] = {0.5f, 0.5f, 0.5f};
  for (int row = 0, base = 40; row < base; ++row)
    for (int k = 0; k < base - row; ++k) {
      const float pos[3] = {float(k) + 0.5f * float(row) - 0.5f * float(base), 0.0f, 0.5f + float(row)};
      cellphys::testing::add_box(w, half, 1.0f, pos);
    }
  auto capture = std::make_shared<CaptureWhole>();
  w.set_runner(capture);
  w.step();
  ASSERT_EQ(capture->images.size(), 1u);
  const std::vector<unsigned char>& image = capture->images[0];
  ASSERT_EQ(bodies_of(image), 820u);
  const size_t ls = w.settings().local_store_bytes;
  std::vector<unsigned char> expected(cellphys::spu::result_bytes(bodies_of(image)));
  const cellphys::spu::IslandJob job{image.data(), image.size(), expected.data(), expected.size()};
  const size_t need = cellphys::spu::ComputeWorker::bytes_needed(job);
  ASSERT_GT(need, ls) << "the island fits the local store: no wide worker";
  cellphys::spu::ComputeWorker alone(need);
  ASSERT_EQ(alone.step(job).status, cellphys::spu::IslandStatus::ok);
  {
    cellphys::test_support::BackwardSharer backward;
    cellphys::spu::ComputeWorker shared(need);
    shared.set_row_sharer(&backward);
    std::vector<unsigned char> got(expected.size());
    ASSERT_EQ(shared.step({image.data(), image.size(), got.data(), got.size()}).status,
              cellphys::spu::IslandStatus::ok);
    EXPECT_GT(backward.shares, 0u) << "the island's products were not shared";
    EXPECT_EQ(got, expected) << "rows taken backwards";
  }
  cellphys::ppe::WorkerPool pool(3, ls, cellphys::spu::LocalStore::kMaxCapacity);
  cellphys::ppe::WorkerPool::Hold held(pool);
  for (int wave = 0; wave < 3; ++wave) {
    std::vector<unsigned char> got(expected.size());
    std::vector<cellphys::spu::IslandReport> reports;
    pool.run({{image.data(), image.size(), got.data(), got.size()}}, reports);
    ASSERT_EQ(reports.at(0).status, cellphys::spu::IslandStatus::ok) << "wave " << wave;
    ASSERT_EQ(got, expected) << "wave " << wave;
  }
}

// A world's pool follows its settings: grown, shrunk and back between steps, the world steps on
// the bits of one worker.
TEST(Threads, PoolResizedBetweenStepsKeepsTheBits) {
  const SceneRun r{"pile65", 40};
  auto w = scene_world(r.scene, 1);
  for (int s = 0; s < r.steps; ++s) {
    auto set = w->settings();
    set.workers = 1 + s % 4;
    w->set_settings(set);
    w->step();
  }
  EXPECT_EQ(w->state_hash(), run_alone(r, 1));
}

}  // namespace
