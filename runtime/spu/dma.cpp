#include "runtime/spu/dma.h"

#include <cstring>
#include <string>

namespace cellphys::spu {

namespace {
bool aligned16(const void* p) { return reinterpret_cast<uintptr_t>(p) % 16 == 0; }
bool legal_size(size_t n) { return n == 1 || n == 2 || n == 4 || n == 8 || (n > 0 && n % 16 == 0); }
}  // namespace

Dma::~Dma() { wait_all(); }

void Dma::enqueue(void* dst, const void* src, size_t bytes, unsigned tag, const void* ls_side) {
  if (tag >= kNumTags) throw DmaError("DMA: tag " + std::to_string(tag) + " out of range 0..31");
  if (!legal_size(bytes))
    throw DmaError("DMA: size " + std::to_string(bytes) + " is not 1, 2, 4, 8 or a multiple of 16");
  if (!aligned16(dst) || !aligned16(src)) throw DmaError("DMA: addresses must be 16-byte aligned");
  if (!ls_.contains(ls_side, bytes)) throw DmaError("DMA: the local-store side is outside the local store");
  // a transfer over 16 KiB is a DMA list of 16 KiB elements
  for (size_t off = 0; off < bytes; off += kMaxTransfer) {
    if (pending_ == kMaxPending) wait_all();  // the hardware queue is finite too
    const size_t n = bytes - off < kMaxTransfer ? bytes - off : kMaxTransfer;
    queue_[pending_++] = {static_cast<unsigned char*>(dst) + off, static_cast<const unsigned char*>(src) + off, n, tag};
  }
}

void Dma::get(void* ls_dst, const void* main_src, size_t bytes, unsigned tag) {
  enqueue(ls_dst, main_src, bytes, tag, ls_dst);
  bytes_in_ += bytes;
}

void Dma::put(void* main_dst, const void* ls_src, size_t bytes, unsigned tag) {
  enqueue(main_dst, ls_src, bytes, tag, ls_src);
  bytes_out_ += bytes;
}

void Dma::wait(uint32_t tag_mask) {
  int kept = 0;
  for (int i = 0; i < pending_; ++i) {
    const Transfer& t = queue_[i];
    if (tag_mask & (1u << t.tag))
      std::memcpy(t.dst, t.src, t.bytes);
    else
      queue_[kept++] = t;
  }
  pending_ = kept;
}

}  // namespace cellphys::spu
