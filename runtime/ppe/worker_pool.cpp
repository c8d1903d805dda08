#include "runtime/ppe/worker_pool.h"

#include <algorithm>
#include <chrono>
#include <thread>

namespace cellphys::ppe {

WorkerPool::WorkerPool(int workers, size_t local_store_bytes, size_t whole_island_bytes)
    : local_store_bytes_(local_store_bytes), whole_island_bytes_(whole_island_bytes) {
  if (workers < 1) workers = 1;
  for (int i = 0; i < workers; ++i) workers_.push_back(std::make_unique<spu::ComputeWorker>(local_store_bytes));
  if (workers > 1)
    for (auto& w : workers_) w->set_row_sharer(this);
  wide_.resize(workers);
  // worker 0 is the calling thread; the others wait for work
  for (int i = 1; i < workers; ++i) threads_.emplace_back([this, i] { loop(i); });
}

WorkerPool::~WorkerPool() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  wake_.notify_all();
  for (auto& t : threads_) t.join();
}

spu::ComputeWorker& WorkerPool::worker_for(int index, const spu::IslandJob& job) {
  const size_t need = local_store_bytes_ < whole_island_bytes_ ? spu::ComputeWorker::bytes_needed(job) : 0;
  if (need <= local_store_bytes_ || need > whole_island_bytes_) return *workers_[index];
  std::unique_ptr<spu::ComputeWorker>& wide = wide_[index];
  if (!wide || wide->local_store().capacity() < need) {
    // a quarter more: an island that grows a little fits still
    wide = std::make_unique<spu::ComputeWorker>(std::min(need + need / 4, whole_island_bytes_));
    if (!threads_.empty()) wide->set_row_sharer(this);
  }
  return *wide;
}

void WorkerPool::work(int index, TaskRef task, size_t count) {
  for (size_t k; (k = next_.fetch_add(1, std::memory_order_relaxed)) < count;) task.call(task.context, k, index);
}

namespace {

void cpu_relax() {
#if defined(__x86_64__) || defined(__i386__)
  __builtin_ia32_pause();
#endif
}

// Spins while `waiting` holds, for up to kSpinTime unless `held` holds too: a step's tasks
// follow one another within microseconds (pack, then integrate), and waking a thread asleep
// on a condition variable takes tens of them, as long as a small task. Held past kSpinTime,
// it yields now and then, so other rooms' threads on the same cores still get them.
template <class Pred, class Held>
void spin_while(Pred waiting, Held held) {
  constexpr auto kSpinTime = std::chrono::microseconds(50);
  const auto start = std::chrono::steady_clock::now();
  for (int i = 0; waiting(); ++i) {
    cpu_relax();
    if (i % 64 != 63 || std::chrono::steady_clock::now() - start <= kSpinTime) continue;
    if (!held()) return;
    std::this_thread::yield();
  }
}

}  // namespace

void WorkerPool::loop(int index) {
  uint64_t seen = 0;
  for (;;) {
    spin_while([&] {
                 help();
                 return generation_.load(std::memory_order_acquire) == seen;
               },
               [&] { return held_.load(std::memory_order_relaxed) > 0; });
    TaskRef task;
    size_t count;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      wake_.wait(lock, [&] { return stop_ || generation_ != seen; });
      if (stop_) return;
      seen = generation_;
      if (!task_.call) continue;  // a late waker finds the task over
      task = task_, count = count_;
      ++joined_;
    }
    work(index, task, count);
    {
      std::lock_guard<std::mutex> lock(mutex_);
      --joined_;
    }
    done_.notify_all();
  }
}

WorkerPool::Hold::Hold(WorkerPool& pool, bool threads) : pool_(pool), threads_(threads), was_alone_(pool.alone_) {
  if (!threads_) {
    pool_.alone_ = true;
    return;
  }
  if (pool_.threads_.empty() || pool_.held_.fetch_add(1, std::memory_order_relaxed) > 0) return;
  {  // wakes the sleeping threads with no task: they find none and spin for the next
    std::lock_guard<std::mutex> lock(pool_.mutex_);
    ++pool_.generation_;
  }
  pool_.wake_.notify_all();
}

WorkerPool::Hold::~Hold() {
  if (!threads_)
    pool_.alone_ = was_alone_;
  else if (!pool_.threads_.empty())
    pool_.held_.fetch_sub(1, std::memory_order_relaxed);
}

void WorkerPool::run_task(size_t count, TaskRef task) {
  if (count == 0) return;
  if (threads_.empty() || count == 1 || alone_) {
    for (size_t k = 0; k < count; ++k) task.call(task.context, k, 0);
    return;
  }
  {
    std::lock_guard<std::mutex> lock(mutex_);
    task_ = task;
    count_ = count;
    next_.store(0, std::memory_order_relaxed);
    ++generation_;
  }
  wake_.notify_all();
  work(0, task, count);
  // Spins up to 50 µs (helping with a big island's rows if another thread shares them), then
  // sleeps. Spinning on while held, to help for as long as another thread solves, cost
  // world1000's step 5-7% on 2 workers and gained the large pyramid 1%: the thread that posts
  // a task mostly takes its first item, the biggest island, while the others spin in loop().
  spin_while([&] {
               help();
               return joined_.load(std::memory_order_acquire) != 0;
             },
             [] { return false; });
  // Every item is taken; the threads that joined finish theirs (what they wrote is published
  // by the lock they leave under).
  std::unique_lock<std::mutex> lock(mutex_);
  done_.wait(lock, [&] { return joined_ == 0; });
  task_ = {nullptr, nullptr};
}

void WorkerPool::share(size_t count, size_t grain, RangeFn fn, void* context) {
  grain = grain ? grain : 1;
  Offer offer;
  offer.fn = fn, offer.context = context, offer.count = count, offer.grain = grain;
  offer.ranges = (count + grain - 1) / grain;
  Offer* none = nullptr;
  const bool offered = !alone_ && offer.ranges > 1 && offer_.compare_exchange_strong(none, &offer);
  for (size_t r; (r = offer.next.fetch_add(1, std::memory_order_relaxed)) < offer.ranges;)
    fn(context, r * grain, std::min(count, (r + 1) * grain));
  if (!offered) return;
  // Withdrawn, then wait for the threads that may have found it: a helper counts itself
  // before it looks (help()), so either it sees the offer gone or this sees it counted.
  offer_.store(nullptr);
  while (helping_.load() != 0) cpu_relax();
}

void WorkerPool::help() {
  if (!offer_.load(std::memory_order_relaxed)) return;
  helping_.fetch_add(1);
  if (Offer* o = offer_.load())
    for (size_t r; (r = o->next.fetch_add(1, std::memory_order_relaxed)) < o->ranges;)
      o->fn(o->context, r * o->grain, std::min(o->count, (r + 1) * o->grain));
  helping_.fetch_sub(1);
}

void WorkerPool::run(const std::vector<spu::IslandJob>& jobs, std::vector<spu::IslandReport>& reports) {
  reports.assign(jobs.size(), spu::IslandReport{});
  // Small islands go to a worker a run at a time, which it integrates together (step_batch);
  // a larger one alone, so the largest spread over the threads first.
  runs_.clear();
  for (size_t k = 0; k < jobs.size();) {
    size_t e = k + 1;
    if (jobs[k].bytes <= kSmallImageBytes)
      while (e < jobs.size() && e - k < kJobsPerRun && jobs[e].bytes <= kSmallImageBytes) ++e;
    runs_.push_back({k, e});
    k = e;
  }
  for_each(runs_.size(), [&](size_t r, int thread) {
    const size_t b = runs_[r].first, e = runs_[r].second;
    step_on(thread, &jobs[b], e - b, &reports[b]);
  });
}

void WorkerPool::step_on(int thread, const spu::IslandJob* jobs, size_t count, spu::IslandReport* reports) {
  for (size_t k = 0; k < count;) {
    size_t e = k + 1;
    if (jobs[k].bytes <= kSmallImageBytes)
      while (e < count && jobs[e].bytes <= kSmallImageBytes) ++e;
    worker_for(thread, jobs[k]).step_batch(jobs + k, e - k, reports + k);
    k = e;
  }
}

}  // namespace cellphys::ppe
