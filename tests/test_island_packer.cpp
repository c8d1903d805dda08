// The order an island image lists its contacts in: sort_contacts_by_pair against std::sort by
// (body a, body b, index), for lists already in order, in two runs, in many, and with body ids
// too wide for its 64-bit radix keys.
#include "runtime/ppe/island_packer.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>

namespace cellphys::ppe {
namespace {

std::vector<uint32_t> by_std_sort(const std::vector<WorldContact>& contacts, std::vector<uint32_t> cs) {
  std::sort(cs.begin(), cs.end(), [&](uint32_t x, uint32_t y) {
    const WorldContact &a = contacts[x], &b = contacts[y];
    return a.a != b.a ? a.a < b.a : a.b != b.b ? a.b < b.b : x < y;
  });
  return cs;
}

TEST(PackContactOrder, IsStdSortsForEveryShapeOfInput) {
  std::mt19937 rng(11);
  PackScratch scratch;
  for (uint32_t id_bits : {1u, 4u, 13u, 31u, 32u})  // 31 and 32: keys wider than 64 bits
    for (size_t n : {size_t(0), size_t(1), size_t(2), size_t(63), size_t(64), size_t(500), size_t(20000)}) {
      const uint32_t mask = id_bits == 32 ? 0xffffffffu : (1u << id_bits) - 1;
      std::vector<WorldContact> contacts(n + n / 3);
      for (WorldContact& c : contacts) c.a = rng() & mask, c.b = rng() & mask;
      // An island's contacts: a subset of the step's, ascending, as the islands stage lists them.
      std::vector<uint32_t> island;
      for (uint32_t c = 0; c < contacts.size(); ++c)
        if (island.size() < n && rng() % 4 != 0) island.push_back(c);
      const std::vector<uint32_t> sorted = by_std_sort(contacts, island);
      for (int shape = 0; shape < 4; ++shape) {
        std::vector<uint32_t> cs = island;  // 0: in no order
        if (shape == 1) cs = sorted;  // already in order
        if (shape == 2 || shape == 3) {  // two sorted runs: a rotation, or a list in order spliced into another
          cs = sorted;
          if (shape == 2) std::rotate(cs.begin(), cs.begin() + ptrdiff_t(cs.size() / 3), cs.end());
          if (shape == 3 && cs.size() > 2) {
            std::vector<uint32_t> odd, even;
            for (size_t k = 0; k < cs.size(); ++k) (k % 2 ? odd : even).push_back(cs[k]);
            cs = even;
            cs.insert(cs.end(), odd.begin(), odd.end());
          }
        }
        const std::vector<uint32_t> expect = by_std_sort(contacts, cs);
        sort_contacts_by_pair(contacts, cs, scratch);
        ASSERT_EQ(cs, expect) << id_bits << "-bit ids, " << n << " contacts, shape " << shape;
      }
    }
}

}  // namespace
}  // namespace cellphys::ppe
