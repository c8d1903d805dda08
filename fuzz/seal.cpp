#include "fuzz/seal.h"

#include <cstdint>
#include <cstring>

#include "runtime/ppe/wire.h"
#include "runtime/spu/island_image.h"

namespace cellphys::fuzz {

namespace {

using namespace cellphys::ppe::wire;

// A wire record's checksum, as wire.cpp computes it: its header with the field zero, then the
// bytes after it.
template <class Header>
void seal_record(std::vector<unsigned char>& msg, size_t at, size_t len) {
  Header h;
  std::memcpy(&h, msg.data() + at, sizeof h);
  h.checksum = 0;
  h.checksum = spu::checksum(msg.data() + at + sizeof h, len - sizeof h,
                             spu::checksum(reinterpret_cast<const unsigned char*>(&h), sizeof h));
  std::memcpy(msg.data() + at, &h, sizeof h);
}

// How many records the header promises; 0 when there is no header.
uint32_t records(const std::vector<unsigned char>& msg) {
  if (msg.size() < sizeof(BatchHeader)) return 0;
  BatchHeader h;
  std::memcpy(&h, msg.data(), sizeof h);
  return h.count;
}

}  // namespace

void seal_snapshot(std::vector<unsigned char>& b) {
  if (b.size() < 32) return;
  const uint64_t payload = b.size() - 32;
  std::memcpy(b.data() + 16, &payload, 8);
  const uint32_t sum = spu::checksum(b.data() + 32, b.size() - 32);
  std::memcpy(b.data() + 24, &sum, 4);
}

void seal_jobs(std::vector<unsigned char>& msg) {
  const uint32_t count = records(msg);
  size_t at = sizeof(BatchHeader);
  for (uint32_t k = 0; k < count && msg.size() - at >= sizeof(JobRecord); ++k) {
    JobRecord r;
    std::memcpy(&r, msg.data() + at, sizeof r);
    if (r.num_bodies == 0 || r.num_bodies > (1u << 20) ||
        r.image_bytes < sizeof(gen::Island_Header) + size_t{r.num_bodies} * sizeof(gen::Rigid_Body))
      break;
    const size_t len = job_record_bytes(r.image_bytes, r.num_bodies);
    if (len > msg.size() - at) break;
    seal_record<JobRecord>(msg, at, len);
    at += len;
  }
  if (msg.size() >= sizeof(BatchHeader)) seal_batch(msg);
}

void seal_results(std::vector<unsigned char>& msg) {
  const uint32_t count = records(msg);
  size_t at = sizeof(BatchHeader);
  for (uint32_t k = 0; k < count && msg.size() - at >= sizeof(ResultRecord); ++k) {
    ResultRecord r;
    std::memcpy(&r, msg.data() + at, sizeof r);
    if (r.num_bodies > (1u << 20)) break;
    const size_t len = result_record_bytes(r.num_bodies);
    if (len > msg.size() - at) break;
    seal_record<ResultRecord>(msg, at, len);
    at += len;
  }
  if (msg.size() >= sizeof(BatchHeader)) seal_batch(msg);
}

}  // namespace cellphys::fuzz
