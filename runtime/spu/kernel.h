// The compute kernel: one packed island in, its change of velocity and advanced state out.
// Stateless: everything it needs is in the island's bytes; everything it touches is in the
// worker's local store, filled and emptied by (emulated) DMA.
#pragma once
#include <array>
#include <cstddef>
#include <string>
#include <vector>

#include "runtime/spu/dma.h"
#include "runtime/spu/integrators.h"
#include "runtime/spu/island_image.h"
#include "runtime/spu/local_store.h"
#include "runtime/spu/row_sharing.h"
#include "runtime/spu/workspace.h"

namespace cellphys::spu {

struct IslandReport {
  IslandStatus status = IslandStatus::ok;
  uint32_t solver_iterations = 0;
  uint32_t solves = 0;
  uint32_t halvings = 0;  // deepest halving used
  uint32_t substeps = 0;
  uint32_t solver_code = 0;
  uint32_t rejected = 0;  // Rosenbrock steps rejected by the error estimate
  Footprint footprint;    // bytes per region, as accounted before any work
  size_t local_store_peak = 0;
  std::string error;  // for does_not_fit and malformed
};

/// One island to step: its packed image and where its result goes (both in main memory,
/// 16-byte aligned; the result must hold result_bytes(num_bodies) bytes).
struct IslandJob {
  const unsigned char* image = nullptr;
  size_t bytes = 0;
  unsigned char* result = nullptr;
  size_t result_capacity = 0;
  /// An image this process packed (unsealed: IslandBuilder::finish(img, false)) for this
  /// worker to step now, which nothing else reads: its checksum is not checked, nor its
  /// contents beyond the header and section table (debug builds check them all), and its result
  /// carries no checksum. An image from anywhere else, a wire or a file, is never trusted.
  bool trusted = false;
};

class ComputeWorker {
 public:
  explicit ComputeWorker(size_t local_store_bytes = LocalStore::kDefaultCapacity);
  /// Steps one island. A failed or refused island's result carries its bodies unchanged.
  IslandReport step(const unsigned char* image, size_t bytes, unsigned char* result, size_t result_capacity);
  IslandReport step(const IslandJob& job);
  /// Steps islands in order, double-buffered: the next island is fetched while one computes.
  /// Results are identical to stepping each alone.
  void step_batch(const IslandJob* jobs, size_t count, IslandReport* reports);
  LocalStore& local_store() { return ls_; }
  const Dma& dma() const { return dma_; }
  /// The local store an island needs (its footprint, double buffering counted), read from its
  /// header and section table as step() reads them; 0 for an image step() would refuse as
  /// malformed.
  static size_t bytes_needed(const IslandJob& job);
  /// Threads that may take rows of a big island's products while this worker solves it
  /// (row_sharing.h); null (the default): the worker runs them all. Results are the same.
  void set_row_sharer(RowSharer* sharer) { sharer_ = sharer; }

 private:
  // Islands integrated together at most (step_together): their lanes fill each kernel's SIMD
  // batches; the local store and its allocation stack bound how many fit.
  static constexpr size_t kMaxTogether = 16;
  static constexpr size_t kBatchReserve = 32;
  struct Plan {
    gen::Island_Header header{};
    IslandCounts counts;
    Footprint footprint;  // computed once: the fit check, the report and the workspace use it
    bool ascending = false;  // sections in increasing force type: may be evaluated with others
    unsigned out_tag = 0;
  };
  // One island between its fetch and its result.
  struct Active {
    StepContext c;
    Workspace ws;
    size_t mark = 0;
    bool ready = false;
    bool singular = false;  // a diagonal block of its first step could not be inverted
    bool failed = false;    // its first step failed (singular, solve or rotation): stepped again alone
  };
  bool plan(const IslandJob& job, Plan& p, IslandReport& r);
  bool begin(const IslandJob& job, const Plan& p, unsigned char* in, unsigned char* out, IslandReport& r, Active& a);
  bool integrate(const Plan& p, StepContext& c, IslandReport& r);
  void finish(const IslandJob& job, const Plan& p, unsigned char* out, const StepContext& c, bool ok, IslandReport& r);
  void compute(const IslandJob& job, const Plan& p, unsigned char* in, unsigned char* out, IslandReport& r);
  bool can_go_together(size_t k, const IslandReport* reports) const;
  static size_t together_bytes(size_t k, const IslandReport* reports);
  size_t together_end(size_t k, size_t count, const IslandReport* reports) const;
  void step_together(const IslandJob* jobs, size_t begin_k, size_t end_k, IslandReport* reports);
  void step_each(const IslandJob* jobs, size_t begin_k, size_t end_k, IslandReport* reports);
  LocalStore ls_;
  Dma dma_;
  RowSharer* sharer_ = nullptr;
  std::vector<Plan> plans_;  // step_batch's, kept so a warm worker allocates nothing
  std::vector<char> ok_;
  std::array<Active, kMaxTogether> active_{};
  std::array<unsigned char*, kMaxTogether> in_{}, out_{};
  std::array<ForceTargets, kMaxTogether> targets_{};
  std::array<ForceJob, kMaxTogether> force_jobs_{};
};

}  // namespace cellphys::spu
