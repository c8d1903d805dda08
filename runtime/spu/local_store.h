// A compute worker's local store: one fixed-capacity arena (256 KiB by default, the size of
// a Cell SPE's), carved into named regions so every island reports where its bytes went.
// Everything the integration kernel touches lives here; the kernel allocates nothing else.
#pragma once
#include <array>
#include <cassert>
#include <cstddef>
#include <cstdint>
#include <memory>

namespace cellphys::spu {

enum class Region : int {
  input,         // the packed island (header, sections, params, bodies, force instances)
  output,        // Island_Result + Rigid_Body_Step per body
  double_buffer, // the next island's input and the previous island's output in flight
  w,             // W_Element per body
  vectors,       // right-hand side, solution and integrator state vectors
  block_index,   // block-row starts and column indices
  blocks,        // off-diagonal blocks of the scaled system matrix
  scratch,       // phase-shared: diagonal blocks + force batches (assembly) or solver work (solve)
  count
};
inline constexpr int kNumRegions = static_cast<int>(Region::count);
const char* region_name(Region r);

using RegionBytes = std::array<size_t, kNumRegions>;

class LocalStore {
 public:
  static constexpr size_t kDefaultCapacity = 256 * 1024;
  static constexpr size_t kMinCapacity = 1024, kMaxCapacity = size_t{1} << 30;
  static constexpr size_t kAlign = 128;  // a DMA-friendly base alignment

  explicit LocalStore(size_t capacity = kDefaultCapacity);
  LocalStore(const LocalStore&) = delete;
  LocalStore& operator=(const LocalStore&) = delete;

  size_t capacity() const { return capacity_; }
  /// Bump allocation aligned to `align`, a power of two; nullptr when it does not fit (the
  /// caller checked the footprint first, so this is a bug guard, never the way an oversized
  /// island is found). Inline, with a mask for the alignment: a one-body island makes a few
  /// dozen of these, and the two divisions of a general alignment were 2.6% of a sparse step.
  void* allocate(size_t bytes, size_t align, Region region) {
    assert(align != 0 && (align & (align - 1)) == 0);
    const size_t start = (used_ + align - 1) & ~(align - 1);
    if (start + bytes > capacity_ || depth_ == kMaxAllocations) return nullptr;
    stack_[depth_++] = {used_, region};
    region_bytes_[static_cast<int>(region)] += start + bytes - used_;
    used_ = start + bytes;
    if (used_ > peak_) peak_ = used_;
    return base_ + start;
  }
  template <class T>
  T* allocate_array(size_t count, Region region, size_t align = alignof(T)) {
    return static_cast<T*>(allocate(count * sizeof(T), align < 32 ? 32 : align, region));
  }
  /// Frees everything allocated after `mark` (a value of used()).
  void release(size_t mark);
  void reset() { release(0); }
  size_t used() const { return used_; }
  size_t peak() const { return peak_; }
  void reset_peak() { peak_ = used_; }
  const RegionBytes& region_bytes() const { return region_bytes_; }
  bool contains(const void* p, size_t bytes) const;
  unsigned char* base() { return base_; }

 private:
  std::unique_ptr<unsigned char[]> storage_;
  unsigned char* base_ = nullptr;
  size_t capacity_ = 0;
  size_t used_ = 0;
  size_t peak_ = 0;
  RegionBytes region_bytes_{};  // bytes currently allocated per region (with alignment padding)
  struct Allocation {
    size_t start;
    Region region;
  };
  static constexpr int kMaxAllocations = 256;
  std::array<Allocation, kMaxAllocations> stack_{};
  int depth_ = 0;
};

}  // namespace cellphys::spu
