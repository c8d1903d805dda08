// Sharing one island's block rows with threads that have nothing else to do. The kernel is
// stateless and knows no threads: whoever drives it (runtime/ppe's worker pool) may hand it a
// RowSplitter, and an operation whose rows are independent of one another (y = A x, row by
// row) runs its parts through it. Each row is computed as it would be alone, so the result
// does not depend on how many threads took part.
#pragma once

namespace cellphys::spu {

class RowSplitter {
 public:
  virtual ~RowSplitter() = default;
  /// fn(context, part) for every part in [0, parts), each once, some perhaps on other threads;
  /// returns when all are done.
  virtual void run(int parts, void (*fn)(void* context, int part), void* context) = 0;
};

}  // namespace cellphys::spu
