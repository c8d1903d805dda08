#include "runtime/spu/local_store.h"

#include <cstdlib>
#include <stdexcept>

namespace cellphys::spu {

const char* region_name(Region r) {
  switch (r) {
    case Region::input: return "input";
    case Region::output: return "output";
    case Region::double_buffer: return "double_buffer";
    case Region::w: return "w";
    case Region::vectors: return "vectors";
    case Region::block_index: return "block_index";
    case Region::blocks: return "blocks";
    case Region::scratch: return "scratch";
    case Region::count: break;
  }
  return "?";
}

LocalStore::LocalStore(size_t capacity) : capacity_(capacity) {
  if (capacity < kMinCapacity || capacity > kMaxCapacity)
    throw std::invalid_argument("LocalStore: capacity must be between 1 KiB and 1 GiB");
  storage_.reset(new unsigned char[capacity + kAlign]);
  const auto addr = reinterpret_cast<uintptr_t>(storage_.get());
  base_ = storage_.get() + ((kAlign - addr % kAlign) % kAlign);
}

void LocalStore::release(size_t mark) {
  while (depth_ > 0 && stack_[depth_ - 1].start >= mark) {
    const Allocation& a = stack_[--depth_];
    region_bytes_[static_cast<int>(a.region)] -= used_ - a.start;
    used_ = a.start;
  }
}

bool LocalStore::contains(const void* p, size_t bytes) const {
  const auto* c = static_cast<const unsigned char*>(p);
  return c >= base_ && c + bytes <= base_ + capacity_;
}

}  // namespace cellphys::spu
