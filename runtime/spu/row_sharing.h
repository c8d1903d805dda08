// Sharing the rows of a long loop with threads that would otherwise wait. The kernel is
// stateless and single-threaded; a big island's matrix-vector products stream megabytes of
// blocks each (a 5,050-box pyramid: 30,000 blocks, 5.8 MB, more than a core's cache), so a
// second core's reads nearly halve them. The runtime that owns the threads implements this;
// the kernel calls it with ranges whose results are their own rows, computed by the same code
// whoever runs them, so the outcome does not depend on who helped, or whether anyone did.
#pragma once
#include <cstddef>

namespace cellphys::spu {

class RowSharer {
 public:
  using RangeFn = void (*)(void* context, size_t begin, size_t end);
  /// fn(context, begin, end) for consecutive ranges of `grain` items covering [0, count), each
  /// once, some perhaps on other threads; returns when all are done. The caller runs ranges
  /// itself, so this never waits for a thread to become free.
  virtual void share(size_t count, size_t grain, RangeFn fn, void* context) = 0;

 protected:
  ~RowSharer() = default;
};

}  // namespace cellphys::spu
