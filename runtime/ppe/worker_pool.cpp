#include "runtime/ppe/worker_pool.h"

#include <algorithm>

namespace cellphys::ppe {

WorkerPool::WorkerPool(int workers, size_t local_store_bytes, size_t whole_island_bytes)
    : local_store_bytes_(local_store_bytes), whole_island_bytes_(whole_island_bytes) {
  if (workers < 1) workers = 1;
  for (int i = 0; i < workers; ++i) workers_.push_back(std::make_unique<spu::ComputeWorker>(local_store_bytes));
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
  if (!wide || wide->local_store().capacity() < need)  // a quarter more: an island that grows a little fits still
    wide = std::make_unique<spu::ComputeWorker>(std::min(need + need / 4, whole_island_bytes_));
  return *wide;
}

void WorkerPool::work(int index, const std::vector<spu::IslandJob>& jobs, std::vector<spu::IslandReport>& reports) {
  for (size_t k; (k = next_.fetch_add(1, std::memory_order_relaxed)) < jobs.size();) {
    const spu::IslandJob& j = jobs[k];
    reports[k] = worker_for(index, j).step(j.image, j.bytes, j.result, j.result_capacity);
  }
}

void WorkerPool::loop(int index) {
  uint64_t seen = 0;
  for (;;) {
    const std::vector<spu::IslandJob>* jobs;
    std::vector<spu::IslandReport>* reports;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      wake_.wait(lock, [&] { return stop_ || generation_ != seen; });
      if (stop_) return;
      seen = generation_;
      if (!jobs_) continue;  // a late waker finds the run over
      jobs = jobs_, reports = reports_;
      ++joined_;
    }
    work(index, *jobs, *reports);
    {
      std::lock_guard<std::mutex> lock(mutex_);
      --joined_;
    }
    done_.notify_all();
  }
}

void WorkerPool::run(const std::vector<spu::IslandJob>& jobs, std::vector<spu::IslandReport>& reports) {
  reports.assign(jobs.size(), spu::IslandReport{});
  if (jobs.empty()) return;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    jobs_ = &jobs;
    reports_ = &reports;
    next_.store(0, std::memory_order_relaxed);
    ++generation_;
  }
  if (!threads_.empty()) wake_.notify_all();
  work(0, jobs, reports);
  // Every job is taken; the threads that joined finish theirs (their reports are published by
  // the lock they leave under).
  std::unique_lock<std::mutex> lock(mutex_);
  done_.wait(lock, [&] { return joined_ == 0; });
  jobs_ = nullptr;
  reports_ = nullptr;
}

}  // namespace cellphys::ppe
