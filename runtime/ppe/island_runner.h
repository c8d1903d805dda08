// The seam between the world and whatever computes its packed islands: the in-process
// worker pool (the default) or compute nodes in other processes (runtime/ppe/mpi_runner.h).
// A runner only moves bytes: every island is computed by the same stateless kernel
// (spu::ComputeWorker), so where it runs never changes the result.
#pragma once
#include <cstddef>
#include <cstdint>
#include <vector>

#include "runtime/spu/kernel.h"

namespace cellphys::ppe {

/// What a runner moved and what went wrong in one run() call.
struct TransportCounters {
  uint64_t bytes_to_nodes = 0, bytes_from_nodes = 0;  // message bytes on the wire (0 in-process)
  uint32_t messages_to_nodes = 0, messages_from_nodes = 0;
  uint32_t bad_messages = 0;         // results refused on arrival (size, checksum, header)
  uint32_t reassigned_islands = 0;   // islands sent again because their node missed the deadline
  uint32_t dropped_nodes = 0;        // nodes dropped for missing the deadline
  uint32_t nodes = 0;                // nodes that computed in this call
};

class IslandRunner {
 public:
  virtual ~IslandRunner() = default;
  /// Computes every job (given largest first) and returns when each has its result bytes.
  /// A job the runner could not get a sound result for is left with its result's header
  /// zeroed and its report marked malformed: the world recomputes it locally. Never throws
  /// for a node's failure.
  virtual void run(const std::vector<spu::IslandJob>& jobs, std::vector<spu::IslandReport>& reports) = 0;
  /// The local store every kernel gets (WorldSettings::local_store_bytes), set before run().
  virtual void set_local_store(size_t bytes) { (void)bytes; }
  /// The largest island (its local store footprint, bytes) the runner computes whole when it
  /// does not fit the local store; the world splits a bigger one into parts that fit. 0: none.
  virtual size_t whole_island_bytes() const { return 0; }
  /// Counters of the last run() call.
  virtual TransportCounters last_transport() const { return {}; }
  virtual const char* name() const = 0;
};

}  // namespace cellphys::ppe
