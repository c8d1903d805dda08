// radix_sort_pairs against std::sort: the same order for pairs of every id width, with
// repeats, already sorted and reversed input, and the short inputs it sorts by insertion.
#include "runtime/base/radix_sort.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>

namespace cellphys {
namespace {

using Pairs = std::vector<std::pair<uint32_t, uint32_t>>;

TEST(RadixSortPairs, OrdersAsStdSortDoes) {
  std::mt19937 rng(3);
  Pairs buffer;
  for (uint32_t bits : {1u, 5u, 11u, 14u, 17u, 24u, 32u})
    for (size_t n : {size_t(0), size_t(1), size_t(63), size_t(64), size_t(1000), size_t(30000)}) {
      const uint32_t mask = bits == 32 ? 0xffffffffu : (1u << bits) - 1;
      Pairs pairs(n);
      for (auto& p : pairs) p = {rng() & mask, rng() & mask};
      for (int variant = 0; variant < 3; ++variant) {
        Pairs expect = pairs;
        std::sort(expect.begin(), expect.end());
        if (variant == 1) pairs = expect;                          // already sorted
        if (variant == 2) std::reverse(pairs.begin(), pairs.end());  // descending
        Pairs got = pairs;
        radix_sort_pairs(got, buffer);
        ASSERT_EQ(got, expect) << bits << " bits, " << n << " pairs, variant " << variant;
      }
    }
}

}  // namespace
}  // namespace cellphys
