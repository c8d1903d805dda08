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

// Seals each record the batch header promises, as far as they frame (`length` gives a
// record's bytes, 0 when its sizes are out of range), then the header.
template <class Record, class Length>
void seal_batch_records(std::vector<unsigned char>& msg, Length length) {
  if (msg.size() < sizeof(BatchHeader)) return;
  BatchHeader h;
  std::memcpy(&h, msg.data(), sizeof h);
  size_t at = sizeof h;
  for (uint32_t k = 0; k < h.count && msg.size() - at >= sizeof(Record); ++k) {
    Record r;
    std::memcpy(&r, msg.data() + at, sizeof r);
    const size_t len = length(r);
    if (len == 0 || len > msg.size() - at) break;
    seal_record<Record>(msg, at, len);
    at += len;
  }
  seal_batch(msg);
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
  seal_batch_records<JobRecord>(msg, [](const JobRecord& r) -> size_t {
    if (r.num_bodies == 0 || r.num_bodies > (1u << 20) ||
        r.image_bytes < sizeof(gen::Island_Header) + size_t{r.num_bodies} * sizeof(gen::Rigid_Body))
      return 0;
    return job_record_bytes(r.image_bytes, r.num_bodies);
  });
}

void seal_results(std::vector<unsigned char>& msg) {
  seal_batch_records<ResultRecord>(
      msg, [](const ResultRecord& r) -> size_t { return r.num_bodies > (1u << 20) ? 0 : result_record_bytes(r.num_bodies); });
}

}  // namespace cellphys::fuzz
