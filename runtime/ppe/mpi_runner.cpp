#include "runtime/ppe/mpi_runner.h"

#include <mpi.h>
#include <sched.h>

#include <algorithm>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <stdexcept>
#include <string>
#include <thread>

#include "runtime/ppe/wire.h"

namespace cellphys::ppe {

namespace {

constexpr int kTagJob = 1, kTagResult = 2, kTagStop = 3, kTagBye = 4;

double now_ms() {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

// Waiting without burning a core another rank may need: yield for a while, then nap.
class Idle {
 public:
  void reset() { spins_ = 0; }
  void wait() {
    if (++spins_ < 200) {
      sched_yield();
    } else {
      std::this_thread::sleep_for(std::chrono::microseconds(50));
    }
  }

 private:
  int spins_ = 0;
};

void check(int rc, const char* what) {
  if (rc != MPI_SUCCESS) throw std::runtime_error(std::string("MPI: ") + what + " failed");
}

}  // namespace

MpiSession::MpiSession(int* argc, char*** argv) {
  int provided = 0;
  check(MPI_Init_thread(argc, argv, MPI_THREAD_FUNNELED, &provided), "MPI_Init_thread");
  MPI_Comm_rank(MPI_COMM_WORLD, &rank_);
  MPI_Comm_size(MPI_COMM_WORLD, &size_);
}

MpiSession::~MpiSession() {
  int finalized = 0;
  MPI_Finalized(&finalized);
  if (!finalized) MPI_Finalize();
}

struct MpiRunner::Send {
  std::vector<unsigned char> bytes;
  MPI_Request request = MPI_REQUEST_NULL;
  int node = 0;
};

MpiRunner::MpiRunner(const MpiOptions& options) : options_(options) {
  int size = 1;
  MPI_Comm_size(MPI_COMM_WORLD, &size);
  for (int r = 1; r < size; ++r) {
    Node n;
    n.rank = r;
    nodes_.push_back(n);
  }
}

MpiRunner::~MpiRunner() {
  try {
    stop();
  } catch (...) {
  }
}

int MpiRunner::live_nodes() const {
  return static_cast<int>(std::count_if(nodes_.begin(), nodes_.end(), [](const Node& n) { return n.live; }));
}

std::vector<uint64_t> MpiRunner::islands_per_node() const {
  std::vector<uint64_t> v;
  for (const Node& n : nodes_) v.push_back(n.islands);
  return v;
}

MpiRunner::Node* MpiRunner::least_loaded() {
  Node* best = nullptr;
  for (Node& n : nodes_)
    if (n.live && (!best || n.load < best->load)) best = &n;  // ties: the lowest rank
  return best;
}

void MpiRunner::dispatch(const std::vector<uint32_t>& order) {
  for (uint32_t k : order) {
    const spu::IslandJob& j = (*jobs_)[k];
    Node* n = least_loaded();
    if (!n) {
      compute_here(k);
      continue;
    }
    gen::Island_Header ih;
    std::memcpy(&ih, j.image, sizeof ih);
    n->plan.push_back(k);
    n->load += static_cast<double>(wire::job_record_bytes(j.bytes, ih.num_bodies));
  }
  for (Node& n : nodes_)
    if (!n.plan.empty()) send_batch(n);
}

void MpiRunner::send_batch(Node& node) {
  // A message's size is an int in MPI: a node's share beyond kMaxBatch goes in several.
  constexpr size_t kMaxBatch = size_t{1} << 30;
  size_t first = 0;
  while (first < node.plan.size()) {
    auto s = std::make_unique<Send>();
    s->node = node.rank;
    Batch b;
    b.token = ++next_token_;
    wire::begin_batch(wire::kJobsMagic, sequence_, local_store_bytes_, s->bytes);
    size_t total = sizeof(wire::BatchHeader), end = first;
    for (; end < node.plan.size(); ++end) {
      const spu::IslandJob& j = (*jobs_)[node.plan[end]];
      gen::Island_Header ih;
      std::memcpy(&ih, j.image, sizeof ih);
      const size_t bytes = wire::job_record_bytes(j.bytes, ih.num_bodies);
      if (end > first && total + bytes > kMaxBatch) break;
      total += bytes;
    }
    s->bytes.reserve(total);
    for (size_t i = first; i < end; ++i) {
      const uint32_t k = node.plan[i];
      const spu::IslandJob& j = (*jobs_)[k];
      wire::append_job(j.image, j.bytes, k, s->bytes);
      owner_[k] = b.token;
      b.jobs.push_back(k);
    }
    wire::seal_batch(s->bytes);
    check(MPI_Isend(s->bytes.data(), static_cast<int>(s->bytes.size()), MPI_BYTE, node.rank, kTagJob, MPI_COMM_WORLD,
                    &s->request),
          "MPI_Isend");
    last_.bytes_to_nodes += s->bytes.size();
    ++last_.messages_to_nodes;
    sends_.push_back(std::move(s));
    if (node.queue.empty()) node.last_heard = now_ms();
    node.queue.push_back(std::move(b));
    first = end;
  }
  node.plan.clear();
}

void MpiRunner::refuse(uint32_t job, const std::string& why) {
  // unsound: the world recomputes it (IslandRunner's contract)
  const spu::IslandJob& j = (*jobs_)[job];
  ++last_.bad_messages;
  std::memset(j.result, 0, std::min<size_t>(j.result_capacity, sizeof(gen::Island_Result)));
  spu::IslandReport& r = (*reports_)[job];
  r = spu::IslandReport{};
  r.status = spu::IslandStatus::malformed;
  r.error = why;
  done_[job] = 1;
  --pending_;
}

void MpiRunner::receive(Node& n, const std::vector<unsigned char>& msg) {
  // a node answers its batches in the order they were sent (MPI keeps the order)
  Batch b = std::move(n.queue.front());
  n.queue.pop_front();
  n.last_heard = now_ms();
  const std::string from = "from rank " + std::to_string(n.rank) + ": ";
  const std::string why = wire::read_results(
      msg.data(), msg.size(), sequence_, *jobs_, *reports_, [&](uint32_t k) { return owner_[k] == b.token && !done_[k]; },
      [&](uint32_t k, const std::string& bad) {
        if (!bad.empty()) return refuse(k, from + bad);
        done_[k] = 1;
        --pending_;
        ++n.islands;
      });
  for (uint32_t k : b.jobs)
    if (!done_[k] && owner_[k] == b.token) refuse(k, from + why);
}

void MpiRunner::compute_here(uint32_t job) {
  const spu::IslandJob& j = (*jobs_)[job];
  if (!local_ || local_->local_store().capacity() != local_store_bytes_)
    local_ = std::make_unique<spu::ComputeWorker>(local_store_bytes_);
  (*reports_)[job] = local_->step(j.image, j.bytes, j.result, j.result_capacity);
  ++local_islands_;
  if (!done_[job]) {
    done_[job] = 1;
    --pending_;
  }
}

void MpiRunner::run(const std::vector<spu::IslandJob>& jobs, std::vector<spu::IslandReport>& reports) {
  if (stopped_) throw std::logic_error("MpiRunner::run after stop()");
  last_ = TransportCounters{};
  reports.assign(jobs.size(), spu::IslandReport{});
  if (jobs.empty()) return;
  ++sequence_;
  jobs_ = &jobs;
  reports_ = &reports;
  owner_.assign(jobs.size(), 0);
  done_.assign(jobs.size(), 0);
  pending_ = jobs.size();
  for (Node& n : nodes_) n.load = 0, n.queue.clear(), n.plan.clear();

  std::vector<uint32_t> order(jobs.size());
  for (uint32_t k = 0; k < jobs.size(); ++k) order[k] = k;
  dispatch(order);
  std::vector<unsigned char> buf;
  Idle idle;
  while (pending_ > 0) {
    int flag = 0;
    MPI_Status st;
    check(MPI_Iprobe(MPI_ANY_SOURCE, kTagResult, MPI_COMM_WORLD, &flag, &st), "MPI_Iprobe");
    if (flag) {
      idle.reset();
      int count = 0;
      MPI_Get_count(&st, MPI_BYTE, &count);
      buf.resize(static_cast<size_t>(count));
      check(MPI_Recv(buf.data(), count, MPI_BYTE, st.MPI_SOURCE, kTagResult, MPI_COMM_WORLD, MPI_STATUS_IGNORE),
            "MPI_Recv");
      last_.bytes_from_nodes += static_cast<uint64_t>(count);
      ++last_.messages_from_nodes;
      Node& n = nodes_[static_cast<size_t>(st.MPI_SOURCE - 1)];
      if (!n.live || n.queue.empty()) continue;  // a dropped node's late answer
      receive(n, buf);
      continue;
    }
    // Deadline: a node with batches outstanding that has said nothing for too long.
    const double t = now_ms();
    for (Node& n : nodes_) {
      if (!n.live || n.queue.empty() || t - n.last_heard < options_.deadline_ms) continue;
      n.live = false;
      ++last_.dropped_nodes;
      std::vector<uint32_t> orphans;
      for (const Batch& b : n.queue)
        for (uint32_t k : b.jobs)
          if (!done_[k]) orphans.push_back(k);
      n.queue.clear();
      std::sort(orphans.begin(), orphans.end());  // the given order: largest first
      last_.reassigned_islands += static_cast<uint32_t>(orphans.size());
      dispatch(orphans);
    }
    idle.wait();
  }
  // Every sent buffer stays until its send completes (a dropped node's may never).
  for (auto it = sends_.begin(); it != sends_.end();) {
    int done = 0;
    MPI_Test(&(*it)->request, &done, MPI_STATUS_IGNORE);
    if (done) it = sends_.erase(it);
    else ++it;
  }
  for (const Node& n : nodes_) last_.nodes += n.live ? 1 : 0;
  jobs_ = nullptr;
  reports_ = nullptr;
}

void MpiRunner::stop() {
  if (stopped_) return;
  stopped_ = true;
  // Not MPI_Send: a hung node's full receive queue would block a blocking send for ever, before
  // the deadline below could name it.
  for (const Node& n : nodes_) {
    auto s = std::make_unique<Send>();
    s->node = n.rank;
    MPI_Isend(nullptr, 0, MPI_BYTE, n.rank, kTagStop, MPI_COMM_WORLD, &s->request);
    sends_.push_back(std::move(s));
  }
  // Wait for each node's goodbye, discarding late answers of dropped nodes on the way, while
  // the nodes are silent no longer than the deadline.
  std::vector<char> bye(nodes_.size(), 0);
  size_t byes = 0;
  std::vector<unsigned char> buf;
  Idle idle;
  double heard = now_ms();
  while (byes < nodes_.size() && now_ms() - heard < options_.deadline_ms) {
    int flag = 0;
    MPI_Status st;
    MPI_Iprobe(MPI_ANY_SOURCE, MPI_ANY_TAG, MPI_COMM_WORLD, &flag, &st);
    if (!flag) {
      idle.wait();
      continue;
    }
    idle.reset();
    heard = now_ms();
    int count = 0;
    MPI_Get_count(&st, MPI_BYTE, &count);
    buf.resize(static_cast<size_t>(std::max(count, 1)));
    MPI_Recv(buf.data(), count, MPI_BYTE, st.MPI_SOURCE, st.MPI_TAG, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
    const size_t node = static_cast<size_t>(st.MPI_SOURCE - 1);
    if (st.MPI_TAG == kTagBye && node < bye.size() && !bye[node]) bye[node] = 1, ++byes;
  }
  if (byes < nodes_.size()) {
    std::string ranks;
    for (size_t k = 0; k < nodes_.size(); ++k)
      if (!bye[k]) ranks += (ranks.empty() ? "" : ", ") + std::to_string(nodes_[k].rank);
    std::fprintf(stderr,
                 "cellphys: compute node rank %s did not stop within %g ms of being told to; aborting the MPI job "
                 "(the run is complete and its outputs are written)\n",
                 ranks.c_str(), options_.deadline_ms);
    std::fflush(nullptr);
    MPI_Abort(MPI_COMM_WORLD, kExitNodesDidNotStop);  // MPI_Finalize would wait for it forever
  }
  // every node read all it was sent before its goodbye: the sends are complete
  for (auto& s : sends_) MPI_Wait(&s->request, MPI_STATUS_IGNORE);
  sends_.clear();
}

uint64_t run_compute_node(const MpiOptions& options) {
  int rank = 0, size = 1;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  MPI_Comm_size(MPI_COMM_WORLD, &size);
  wire::NodeKernel kernel;
  std::vector<unsigned char> in, out;
  uint64_t received = 0, replies = 0;
  const bool silent_node = options.silent_after >= 0 && rank == size - 1;
  const bool hung_node = options.hang_after >= 0 && rank == size - 1;
  const bool dying_node = options.kill_after >= 0 && rank == size - 1;
  Idle idle;
  for (;;) {
    if (hung_node && received >= static_cast<uint64_t>(options.hang_after))
      for (;;) std::this_thread::sleep_for(std::chrono::seconds(1));  // hook: reads nothing more, until killed
    int flag = 0;
    MPI_Status st;
    check(MPI_Iprobe(0, MPI_ANY_TAG, MPI_COMM_WORLD, &flag, &st), "MPI_Iprobe");
    if (!flag) {
      idle.wait();
      continue;
    }
    idle.reset();
    int count = 0;
    MPI_Get_count(&st, MPI_BYTE, &count);
    in.resize(static_cast<size_t>(std::max(count, 1)));
    check(MPI_Recv(in.data(), count, MPI_BYTE, 0, st.MPI_TAG, MPI_COMM_WORLD, MPI_STATUS_IGNORE), "MPI_Recv");
    if (st.MPI_TAG == kTagStop) break;
    if (st.MPI_TAG != kTagJob) continue;
    if (silent_node || hung_node || dying_node) {  // hooks: count the islands received
      if (silent_node && received >= static_cast<uint64_t>(options.silent_after)) continue;  // answers no more
      wire::BatchHeader h;
      if (static_cast<size_t>(count) >= sizeof h) {
        std::memcpy(&h, in.data(), sizeof h);
        received += h.count;
      }
      // hook: the process dies unannounced, as one the kernel's OOM killer picks (Open MPI then ends the job)
      if (dying_node && received >= static_cast<uint64_t>(options.kill_after)) ::raise(SIGKILL);
    }
    kernel.serve(in.data(), static_cast<size_t>(count), out);
    const std::vector<size_t>& at = kernel.record_offsets();
    if (rank == 1 && options.corrupt_reply >= 0) {
      const uint64_t target = static_cast<uint64_t>(options.corrupt_reply);
      if (target >= replies && target < replies + at.size()) {  // hook: one island damaged on the way
        const size_t i = static_cast<size_t>(target - replies);
        const size_t end = i + 1 < at.size() ? at[i + 1] : out.size();
        out[end - 1] ^= 0x40;
      }
    }
    replies += at.size();
    check(MPI_Send(out.data(), static_cast<int>(out.size()), MPI_BYTE, 0, kTagResult, MPI_COMM_WORLD), "MPI_Send");
  }
  MPI_Send(nullptr, 0, MPI_BYTE, 0, kTagBye, MPI_COMM_WORLD);
  return kernel.islands();
}

}  // namespace cellphys::ppe
