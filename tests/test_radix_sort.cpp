// radix_sort_pairs and radix_sort_keys against std::sort: the same order for values of every
// width and counts of every digit width, with repeats, already sorted and reversed input, and
// the short inputs they sort by insertion.
#include "runtime/base/radix_sort.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>

namespace cellphys {
namespace {

using Pairs = std::vector<std::pair<uint32_t, uint32_t>>;

// Insertion-sorted (under 64), then a digit of 6 to 11 bits as the count grows: each width,
// with key widths that are and are not a whole number of digits.
constexpr size_t kSizes[] = {0, 1, 63, 64, 100, 130, 300, 600, 1000, 2000, 4000, 30000};

TEST(RadixSortPairs, OrdersAsStdSortDoes) {
  std::mt19937 rng(3);
  Pairs buffer;
  for (uint32_t bits : {1u, 5u, 11u, 14u, 17u, 24u, 32u})
    for (size_t n : kSizes) {
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

TEST(RadixSortKeys, OrdersAsStdSortDoes) {
  std::mt19937_64 rng(5);
  std::vector<uint64_t> buffer;
  for (uint32_t bits : {1u, 7u, 11u, 22u, 33u, 45u, 63u, 64u})
    for (size_t n : kSizes) {
      const uint64_t mask = bits == 64 ? ~uint64_t{0} : (uint64_t{1} << bits) - 1;
      std::vector<uint64_t> keys(n);
      for (auto& k : keys) k = rng() & mask;
      for (int variant = 0; variant < 3; ++variant) {
        std::vector<uint64_t> expect = keys;
        std::sort(expect.begin(), expect.end());
        if (variant == 1) keys = expect;
        if (variant == 2) std::reverse(keys.begin(), keys.end());
        std::vector<uint64_t> got = keys;
        radix_sort_keys(got, buffer);
        ASSERT_EQ(got, expect) << bits << " bits, " << n << " keys, variant " << variant;
      }
    }
}

}  // namespace
}  // namespace cellphys
