// Compute nodes over MPI (Open MPI): the reference design's dispatcher model. Rank 0 of MPI_COMM_WORLD
// is the dispatcher: it owns the world, collides, partitions and packs, and an MpiRunner
// ships the packed islands to compute nodes (ranks 1..size-1) as the reference design's wire tables
// (runtime/ppe/wire.h). Islands go largest first to the node with the least work queued; each
// node then gets every island it was given in a wave as one message (a batch) and answers
// with one message. A node holds no state between islands: it rebuilds each image, runs the
// same kernel a worker thread runs (spu::ComputeWorker) and sends back 13 floats per body.
//
// Faults: an island whose result arrives damaged (size, checksum, header) or refused is
// recomputed on the dispatcher, the sound islands of the same batch kept (World::step checks every result); a node with islands outstanding that
// sends nothing for `deadline_ms` is dropped and its islands sent to the others (or computed
// on the dispatcher when none is left). A step returns only when every island has a sound
// result, so the world is never half-stepped. (A node process that dies takes the MPI job
// with it: Open MPI 4.1 without ULFM aborts every rank; the deadline covers a node that
// hangs or falls behind, in a step and at the end.)
#pragma once
#include <cstdint>
#include <deque>
#include <memory>
#include <string>
#include <vector>

#include "runtime/ppe/island_runner.h"

namespace cellphys::ppe {

struct MpiOptions {
  double deadline_ms = 5000;  // a node silent this long with islands outstanding is dropped
  // Test hooks (every rank parses the same command line):
  int corrupt_reply = -1;  // node 1 damages its island result number N (0-based) after sealing it
  int silent_after = -1;   // the last node stops answering once it got N islands (it keeps receiving)
  int hang_after = -1;     // the last node stops reading anything once it got N islands (a hung process)
  int kill_after = -1;     // the last node SIGKILLs itself once it got N islands (a process that dies)
};

/// The exit status of a job whose dispatcher aborted it because a node did not stop: the run
/// itself finished and its outputs were written.
inline constexpr int kExitNodesDidNotStop = 3;

/// The process's MPI session: MPI_Init on construction, MPI_Finalize on destruction.
class MpiSession {
 public:
  MpiSession(int* argc, char*** argv);
  ~MpiSession();
  MpiSession(const MpiSession&) = delete;
  MpiSession& operator=(const MpiSession&) = delete;
  int rank() const { return rank_; }
  int size() const { return size_; }

 private:
  int rank_ = 0, size_ = 1;
};

/// The dispatcher's side (rank 0). Ranks 1..size-1 must be in run_compute_node().
class MpiRunner final : public IslandRunner {
 public:
  explicit MpiRunner(const MpiOptions& options = {});
  ~MpiRunner() override;  // stops the nodes
  MpiRunner(const MpiRunner&) = delete;
  MpiRunner& operator=(const MpiRunner&) = delete;

  void run(const std::vector<spu::IslandJob>& jobs, std::vector<spu::IslandReport>& reports) override;
  TransportCounters last_transport() const override { return last_; }
  const char* name() const override { return "mpi"; }
  void set_local_store(size_t bytes) override { local_store_bytes_ = bytes; }
  int nodes() const { return static_cast<int>(nodes_.size()); }
  int live_nodes() const;
  /// Islands each node computed so far (index 0 is rank 1), and on the dispatcher itself.
  std::vector<uint64_t> islands_per_node() const;
  uint64_t islands_local() const { return local_islands_; }
  /// Tells every node to finish and waits for each to say goodbye, for as long as the nodes
  /// keep silent no longer than deadline_ms. A node that does not answer in that time (hung,
  /// or stuck in a kernel) would hang MPI_Finalize too: the job is then aborted with
  /// MPI_Abort(kExitNodesDidNotStop), naming the ranks on stderr. Idempotent.
  void stop();

 private:
  struct Batch {
    uint32_t token = 0;          // names the batch in owner_
    std::vector<uint32_t> jobs;  // in the order sent (and answered)
  };
  struct Node {
    int rank = 0;
    bool live = true;
    double load = 0;          // bytes queued in this run() call
    std::deque<Batch> queue;  // batches sent, in order; replies come back in this order
    double last_heard = 0;    // ms: last reply, or when its queue last became non-empty
    uint64_t islands = 0;
    std::vector<uint32_t> plan;  // jobs assigned, not yet sent
  };
  struct Send;
  // Largest first (the order given) to the least-loaded live node, then one batch per node;
  // with no node left, computed here.
  void dispatch(const std::vector<uint32_t>& jobs);
  void send_batch(Node& node);
  void receive(Node& node, const std::vector<unsigned char>& msg);
  void refuse(uint32_t job, const std::string& why);
  Node* least_loaded();
  void compute_here(uint32_t job);

  MpiOptions options_;
  std::vector<Node> nodes_;
  uint32_t sequence_ = 0;
  TransportCounters last_;
  bool stopped_ = false;
  uint64_t local_islands_ = 0;
  size_t local_store_bytes_ = 256 * 1024;
  std::unique_ptr<spu::ComputeWorker> local_;
  // the current run() call
  const std::vector<spu::IslandJob>* jobs_ = nullptr;
  std::vector<spu::IslandReport>* reports_ = nullptr;
  std::vector<uint32_t> owner_;  // per job: the token of the batch whose answer counts
  std::vector<char> done_;       // per job: has a sound result, or was refused
  size_t pending_ = 0;
  uint32_t next_token_ = 0;
  std::vector<std::unique_ptr<Send>> sends_;  // outstanding sends (buffers live until complete)
};

/// A compute node's loop (rank > 0): serves islands until the dispatcher stops it. Returns
/// the number of islands computed.
uint64_t run_compute_node(const MpiOptions& options = {});

}  // namespace cellphys::ppe
