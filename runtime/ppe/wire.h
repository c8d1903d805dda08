// The messages between a dispatcher and its compute nodes, in the seed's wire tables
// (codegen/descriptors/structs/wire_*.yaml), with no transport in them (mpi_runner.cpp moves
// them). Both sides are this build's code on the same architecture (little-endian,
// IEEE floats): the bytes are the structs.
//
// Job, dispatcher -> node:
//   JobHeader | the image's header, sections and parameters | Wire_Body_To_Node_Compressed
//   per body | the image's force and contact records
// The node rebuilds the packed island from it (a body's inverse mass and inertia from its
// mass and inertia, zero for a kinematic ghost, flagged in body_flags) and runs the kernel.
// Result, node -> dispatcher:
//   ResultHeader (the kernel's Island_Result inside) | Wire_Node_To_Dispatcher per body
// (no bodies when the kernel refused the island). The dispatcher rebuilds the kernel's
// result bytes from it and the image it sent: bit for bit what the kernel wrote for every
// field the world reads.
// Each message carries a checksum of all its bytes; a damaged one is refused by name.
#pragma once
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "cellphys/gen/layouts.h"
#include "runtime/spu/kernel.h"

namespace cellphys::ppe::wire {

inline constexpr uint32_t kJobMagic = 0x424F4A43u;     // "CJOB"
inline constexpr uint32_t kResultMagic = 0x53455243u;  // "CRES"
inline constexpr uint32_t kVersion = 1;
inline constexpr uint32_t kGhostFlag = 1u;  // Wire_Body_To_Node_Compressed::body_flags

struct JobHeader {
  uint32_t magic = kJobMagic, version = kVersion;
  uint32_t sequence = 0;  // the dispatcher's run() call
  uint32_t job = 0;       // index of the job in that call
  uint32_t image_bytes = 0, num_bodies = 0, prefix_bytes = 0, checksum = 0;
  uint64_t local_store_bytes = 0;
};
static_assert(sizeof(JobHeader) == 40);

struct ResultHeader {
  uint32_t magic = kResultMagic, version = kVersion;
  uint32_t sequence = 0, job = 0;
  uint32_t num_bodies = 0;  // Wire_Node_To_Dispatcher records that follow
  uint32_t checksum = 0;
  uint32_t reserved[2] = {};
  gen::Island_Result result{};  // as the kernel wrote it
};
static_assert(sizeof(ResultHeader) == 80);

/// The job message for a packed island.
void encode_job(const unsigned char* image, size_t bytes, uint32_t sequence, uint32_t job, uint64_t local_store_bytes,
                std::vector<unsigned char>& out);
/// On a node: checks a job message and rebuilds the island's image. "" or the reason.
std::string decode_job(const unsigned char* msg, size_t n, JobHeader& h, std::vector<unsigned char>& image);

/// On a node: the result message for what the kernel wrote.
void encode_result(const JobHeader& job, const unsigned char* result, std::vector<unsigned char>& out);
/// On the dispatcher: checks a result message (its checksum; its sequence, job and bodies
/// against what was sent) and rebuilds the kernel's result bytes into `result` (capacity
/// result_bytes(num_bodies)) and the report. "" or the reason.
std::string decode_result(const unsigned char* msg, size_t n, uint32_t sequence, uint32_t job, const unsigned char* image,
                          unsigned char* result, size_t result_capacity, spu::IslandReport& report);
/// Peeks at a result message's sequence and job (false if it is too short or not a result).
bool peek_result(const unsigned char* msg, size_t n, uint32_t& sequence, uint32_t& job);

/// A compute node's kernel: holds no state between islands but its local store.
class NodeKernel {
 public:
  /// Decodes a job, steps it, encodes the result. A job that does not decode is answered
  /// with a malformed result (the dispatcher recomputes it).
  void serve(const unsigned char* msg, size_t n, std::vector<unsigned char>& out);
  uint64_t islands() const { return islands_; }

 private:
  std::unique_ptr<spu::ComputeWorker> worker_;
  std::vector<unsigned char> image_, result_;
  uint64_t islands_ = 0;
};

/// Bytes of the messages for an island of n bodies whose image is `image_bytes` long.
size_t job_bytes(size_t image_bytes, size_t n);
size_t result_message_bytes(size_t n);

}  // namespace cellphys::ppe::wire
