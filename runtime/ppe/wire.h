// The messages between a dispatcher and its compute nodes, in the reference design's wire tables
// (codegen/descriptors/structs/wire_*.yaml), with no transport in them (mpi_runner.cpp moves
// them). Both sides are this build's code on the same architecture (little-endian,
// IEEE floats): the bytes are the structs.
//
// One message per node and wave carries every island the node was given (a batch), and one
// message carries the node's answers back:
//
// Jobs, dispatcher -> node:
//   BatchHeader (kJobsMagic) | count x [ JobRecord | the image's header, sections and
//   parameters | Wire_Body_To_Node_Compressed per body | the image's force and contact records ]
// The node rebuilds each packed island from its record (a body's inverse mass and inertia
// from its mass and inertia, zero for a kinematic ghost, flagged in body_flags) and runs the
// kernel.
// Results, node -> dispatcher, in the order of the jobs:
//   BatchHeader (kResultsMagic) | count x [ ResultRecord | Wire_Node_To_Dispatcher per body ]
// (no bodies when the kernel refused the island). The dispatcher rebuilds the kernel's result
// bytes from a record and the image it sent: bit for bit what the kernel wrote for every field
// the world reads.
//
// Every record carries a checksum of its own bytes, and the batch header one of itself, so a
// damaged island is refused by name while the sound ones of the same batch are kept. A record
// whose sizes do not frame (a damaged length) ends the walk: the islands after it are refused.
#pragma once
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "cellphys/gen/layouts.h"
#include "runtime/spu/kernel.h"

namespace cellphys::ppe::wire {

inline constexpr uint32_t kJobsMagic = 0x534A4243u;     // "CBJS"
inline constexpr uint32_t kResultsMagic = 0x53524243u;  // "CBRS"
inline constexpr uint32_t kVersion = 2;
inline constexpr uint32_t kGhostFlag = 1u;  // Wire_Body_To_Node_Compressed::body_flags

struct BatchHeader {
  uint32_t magic = 0, version = kVersion;
  uint32_t sequence = 0;  // the dispatcher's run() call
  uint32_t count = 0;     // records that follow
  uint64_t local_store_bytes = 0;  // jobs: the kernel's local store; results: 0
  uint32_t checksum = 0;  // of this header with the field zero
  uint32_t reserved = 0;
};
static_assert(sizeof(BatchHeader) == 32);

struct JobRecord {
  uint32_t job = 0;  // index of the job in the run() call
  uint32_t image_bytes = 0, num_bodies = 0;
  uint32_t checksum = 0;  // of this record (field zero) and its bytes
};
static_assert(sizeof(JobRecord) == 16);

struct ResultRecord {
  uint32_t job = 0;
  uint32_t num_bodies = 0;  // Wire_Node_To_Dispatcher records that follow
  uint32_t checksum = 0;    // of this record (field zero) and its bodies
  // the kernel's Island_Result but for its magic, body count and checksum (rebuilt)
  uint32_t status = 0, island_id = 0, solver_iterations = 0, solves = 0, halvings = 0, substeps = 0, solver_code = 0,
           local_store_bytes = 0, total_bytes = 0;
};
static_assert(sizeof(ResultRecord) == 48);

/// Starts a message: `out` becomes a batch header with no records.
void begin_batch(uint32_t magic, uint32_t sequence, uint64_t local_store_bytes, std::vector<unsigned char>& out);
/// Seals the header (its checksum) once every record is appended.
void seal_batch(std::vector<unsigned char>& out);
/// Checks a message's batch header. "" or the reason.
std::string decode_batch_header(const unsigned char* msg, size_t n, uint32_t magic, BatchHeader& h);

/// Appends a packed island's job record to a jobs batch.
void append_job(const unsigned char* image, size_t bytes, uint32_t job, std::vector<unsigned char>& out);
/// On a node: frames the job record at msg[offset] (advancing offset past it) and rebuilds its
/// island's image. Returns "" or why the record is unsound; `framed` is false when the walk
/// cannot go on (the record's sizes run past the message).
std::string next_job(const unsigned char* msg, size_t n, size_t& offset, JobRecord& rec, std::vector<unsigned char>& image,
                     bool& framed);

/// On a node: appends the result record for what the kernel wrote (`result` of an island of
/// num_bodies bodies; a refusal carries no bodies).
void append_result(uint32_t job, uint32_t num_bodies, const unsigned char* result, std::vector<unsigned char>& out);
/// On the dispatcher: frames the result record at msg[offset] (advancing offset past it).
/// False when no further record can be framed.
bool next_result(const unsigned char* msg, size_t n, size_t& offset, ResultRecord& rec, const unsigned char*& bodies);
/// Checks a framed result record (its checksum; its bodies against the image that was sent,
/// each with a finite state and a unit quaternion) and rebuilds the kernel's result bytes into `result` (capacity result_bytes(num_bodies))
/// and the report. "" or the reason.
std::string decode_result(const ResultRecord& rec, const unsigned char* bodies, const unsigned char* image,
                          unsigned char* result, size_t result_capacity, spu::IslandReport& report);

/// On the dispatcher: reads a node's answer to a jobs batch of wave `sequence` over `jobs`. Each
/// record that frames and names a job `expects` admits (one of this batch not yet answered) is
/// decoded into that job's result and report, and `answered(job, why)` is told "" when it is
/// sound, or why not. Returns why the batch's other jobs have no result: the header's problem,
/// or that the answer held none for them.
std::string read_results(const unsigned char* msg, size_t n, uint32_t sequence, const std::vector<spu::IslandJob>& jobs,
                         std::vector<spu::IslandReport>& reports, const std::function<bool(uint32_t)>& expects,
                         const std::function<void(uint32_t, const std::string&)>& answered);

/// A compute node's kernel: holds no state between islands but its local store.
class NodeKernel {
 public:
  /// Answers a jobs batch: decodes each job, steps it, appends its result, in order. A job
  /// that does not decode is answered with a malformed result (the dispatcher recomputes it);
  /// a batch whose header is damaged, or the jobs after a record that does not frame, get no
  /// answer (the dispatcher recomputes them too).
  void serve(const unsigned char* msg, size_t n, std::vector<unsigned char>& out);
  uint64_t islands() const { return islands_; }
  /// Where each result record of the last answer starts (test hooks damage one).
  const std::vector<size_t>& record_offsets() const { return offsets_; }

 private:
  std::unique_ptr<spu::ComputeWorker> worker_;
  std::vector<unsigned char> image_, result_;
  std::vector<size_t> offsets_;
  uint64_t islands_ = 0;
};

/// Bytes of a job record for an island of n bodies whose image is `image_bytes` long, and of
/// a result record of n bodies.
size_t job_record_bytes(size_t image_bytes, size_t n);
size_t result_record_bytes(size_t n);

}  // namespace cellphys::ppe::wire
