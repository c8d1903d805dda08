// A fixed pool of threads, each with its own compute worker (its own local store). Jobs
// are taken largest-first from a shared counter (small ones a run at a time, which the
// worker integrates together); each island's result goes to its own
// slot, so the outcome is the same whatever the number of workers. An island too big for
// the local store, up to whole_island_bytes, is computed whole by the thread's wide worker,
// whose store is grown to fit it (main memory standing in for blocks streamed through the
// store): the same kernel, so the same result as a store that big. A thread with nothing left
// to take helps with the rows of a big island's products (spu::RowSharer), which another
// thread's kernel shares out while it solves.
#pragma once
#include <atomic>
#include <condition_variable>
#include <cstddef>
#include <type_traits>
#include <memory>
#include <mutex>
#include <thread>
#include <utility>
#include <vector>

#include "runtime/ppe/island_runner.h"
#include "runtime/spu/kernel.h"
#include "runtime/spu/row_sharing.h"

namespace cellphys::ppe {

class WorkerPool : public IslandRunner, public spu::RowSharer {
 public:
  WorkerPool(int workers, size_t local_store_bytes, size_t whole_island_bytes = 0);
  ~WorkerPool() override;
  int size() const { return static_cast<int>(workers_.size()); }
  /// Runs every job (in the given order of priority) and returns when all are done.
  void run(const std::vector<spu::IslandJob>& jobs, std::vector<spu::IslandReport>& reports) override;
  /// task(i, thread) for every i in [0, count), each once, on the pool's threads (the calling
  /// one is thread 0); returns when all are done. Whatever a task writes must be its own.
  template <class Task>
  void for_each(size_t count, Task&& task) {
    using T = std::remove_reference_t<Task>;
    run_task(count, {&task, [](void* t, size_t k, int thread) { (*static_cast<T*>(t))(k, thread); }});
  }
  /// task(begin, end, thread) over [0, count) in ranges of `grain` items taken at a time:
  /// for items of a few hundred nanoseconds, which taken one by one spend as long passing the
  /// shared counter and the neighbours' cache lines between the threads.
  template <class Task>
  void for_ranges(size_t count, size_t grain, Task&& task) {
    grain = grain ? grain : 1;
    for_each((count + grain - 1) / grain, [&](size_t r, int thread) {
      const size_t begin = r * grain;
      task(begin, begin + grain < count ? begin + grain : count, thread);
    });
  }
  /// Steps jobs[0, count) on the kernel of `thread` (called from a task of this pool, on that
  /// thread): runs of small images integrated together, a larger one alone on a kernel with the
  /// store it needs. What run() does with each share it hands out.
  void step_on(int thread, const spu::IslandJob* jobs, size_t count, spu::IslandReport* reports);
  const char* name() const override { return "threads"; }
  /// spu::RowSharer: a kernel's ranges, offered to the pool's threads that are waiting for
  /// work (while a Hold lives they spin and take them within a microsecond; asleep, they do not).
  void share(size_t count, size_t grain, RangeFn fn, void* context) override;
  size_t whole_island_bytes() const override { return whole_island_bytes_; }

  /// While a Hold lives the threads wait for the next task spinning instead of asleep: a step
  /// hands out tasks between serial stages a hundred microseconds long, and a thread woken
  /// from its condition variable joined its task tens of microseconds late (on 2 workers the
  /// narrow phase of the 1,000-body world took longer than on 1). A step holds its pool.
  /// Held with `threads` false, the pool runs every task on the calling thread and leaves its
  /// threads asleep: for a step with no awake body (waking the threads for it doubled its cost
  /// on 2 workers).
  class Hold {
   public:
    explicit Hold(WorkerPool& pool, bool threads = true);
    ~Hold();
    Hold(const Hold&) = delete;
    Hold& operator=(const Hold&) = delete;

   private:
    WorkerPool& pool_;
    bool threads_, was_alone_;
  };

 private:
  // A task without its type (no allocation, unlike std::function): what for_each runs.
  struct TaskRef {
    void* context;
    void (*call)(void*, size_t, int);
  };
  void run_task(size_t count, TaskRef task);
  // Takes ranges of the offered loop, if there is one, until none is left.
  void help();
  void loop(int index);
  // Takes items of the current task until none is left.
  void work(int index, TaskRef task, size_t count);
  spu::ComputeWorker& worker_for(int index, const spu::IslandJob& job);
  std::vector<std::unique_ptr<spu::ComputeWorker>> workers_;
  std::vector<std::unique_ptr<spu::ComputeWorker>> wide_;  // per thread, made on first use
  size_t local_store_bytes_ = 0, whole_island_bytes_ = 0;
  // Islands of at most this many image bytes are handed out kJobsPerRun at a time.
  static constexpr size_t kSmallImageBytes = 8 * 1024, kJobsPerRun = 32;
  std::vector<std::pair<size_t, size_t>> runs_;  // run()'s [first, end) job ranges
  std::vector<std::thread> threads_;
  std::mutex mutex_;
  std::condition_variable wake_, done_;
  TaskRef task_{nullptr, nullptr};  // the current for_each's, held while joined
  size_t count_ = 0;
  std::atomic<size_t> next_{0};  // the next item to take: taken without the lock
  // Written under the lock; read without it too while a thread spins (worker_pool.cpp).
  std::atomic<int> joined_{0};             // threads working on the current task
  std::atomic<uint64_t> generation_{0};
  std::atomic<int> held_{0};  // live Holds
  // The loop a kernel offers (share()): one at a time; a second kernel wanting to share
  // while one is offered runs its ranges alone. `helping` counts the threads that may be
  // inside it, so its owner returns only when they are out.
  struct Offer {
    RangeFn fn;
    void* context;
    size_t count, grain, ranges;
    std::atomic<size_t> next{0};
  };
  std::atomic<Offer*> offer_{nullptr};
  std::atomic<int> helping_{0};
  bool stop_ = false;
  // Set by a Hold without threads, between tasks; read by run_task's calling thread and by
  // share() (on the caller's thread while it is set, as no task runs elsewhere then).
  bool alone_ = false;
};

}  // namespace cellphys::ppe
