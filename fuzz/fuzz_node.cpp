// libFuzzer target for what a compute node decodes from the dispatcher: the input is a jobs
// batch (runtime/ppe/wire.h), sealed again (header and record checksums) so mutations reach
// the records and the islands they rebuild. Whatever the bytes, the node answers with a
// results batch that frames to its end, no more records than jobs, and nothing crashes or
// throws under ASan/UBSan.
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <vector>

#include "fuzz/seal.h"
#include "runtime/ppe/wire.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace cellphys::ppe::wire;
  std::vector<unsigned char> msg(data, data + size);
  cellphys::fuzz::seal_jobs(msg);
  NodeKernel node;
  std::vector<unsigned char> answer;
  node.serve(msg.data(), msg.size(), answer);
  BatchHeader h;
  if (!decode_batch_header(answer.data(), answer.size(), kResultsMagic, h).empty()) __builtin_trap();
  BatchHeader in{};
  if (msg.size() >= sizeof in) std::memcpy(&in, msg.data(), sizeof in);
  if (h.count > in.count || h.count != node.record_offsets().size()) __builtin_trap();
  size_t offset = sizeof h;
  for (uint32_t r = 0; r < h.count; ++r) {
    ResultRecord rec;
    const unsigned char* bodies = nullptr;
    if (!next_result(answer.data(), answer.size(), offset, rec, bodies)) __builtin_trap();
  }
  if (offset != answer.size()) __builtin_trap();
  return 0;
}
