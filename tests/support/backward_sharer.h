// A stand-in for threads that take a shared loop's ranges in any order: runs them last first,
// on the calling thread, counting the loops and recording the ranges.
#pragma once
#include <algorithm>
#include <cstddef>
#include <utility>
#include <vector>

#include "runtime/spu/row_sharing.h"

namespace cellphys::test_support {

struct BackwardSharer : spu::RowSharer {
  size_t shares = 0;
  std::vector<std::pair<size_t, size_t>> ranges;
  void share(size_t count, size_t grain, RangeFn fn, void* context) override {
    ++shares;
    for (size_t r = (count + grain - 1) / grain; r-- > 0;) {
      ranges.push_back({r * grain, std::min(count, (r + 1) * grain)});
      fn(context, ranges.back().first, ranges.back().second);
    }
  }
};

}  // namespace cellphys::test_support
