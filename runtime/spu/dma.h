// Emulated DMA between main memory and a local store, with the Cell's rules checked:
// both addresses 16-byte aligned, sizes of 1, 2, 4 or 8 bytes or a multiple of 16, tags
// 0..31. Transfers over 16 KiB become a DMA list of 16 KiB pieces. The copy happens at
// wait(), not at get()/put(): code that reads a buffer before waiting on its tag sees stale
// bytes and fails its tests, as it would on the hardware.
#pragma once
#include <cstddef>
#include <cstdint>
#include <stdexcept>

#include "runtime/spu/local_store.h"

namespace cellphys::spu {

class DmaError : public std::logic_error {
 public:
  using std::logic_error::logic_error;
};

class Dma {
 public:
  static constexpr size_t kMaxTransfer = 16 * 1024;
  static constexpr int kMaxPending = 64;
  static constexpr unsigned kNumTags = 32;

  explicit Dma(LocalStore& ls) : ls_(ls) {}
  ~Dma();
  /// main memory -> local store
  void get(void* ls_dst, const void* main_src, size_t bytes, unsigned tag);
  /// local store -> main memory
  void put(void* main_dst, const void* ls_src, size_t bytes, unsigned tag);
  /// Completes every transfer whose tag is in the mask (bit t for tag t).
  void wait(uint32_t tag_mask);
  void wait_all() { wait(0xFFFFFFFFu); }
  int pending() const { return pending_; }
  uint64_t bytes_in() const { return bytes_in_; }
  uint64_t bytes_out() const { return bytes_out_; }

 private:
  struct Transfer {
    void* dst;
    const void* src;
    size_t bytes;
    unsigned tag;
  };
  void enqueue(void* dst, const void* src, size_t bytes, unsigned tag, const void* ls_side);
  LocalStore& ls_;
  Transfer queue_[kMaxPending];
  int pending_ = 0;
  uint64_t bytes_in_ = 0, bytes_out_ = 0;
};

}  // namespace cellphys::spu
