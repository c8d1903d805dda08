// PairTable (the contact memory's map) against std::map under random adds, finds and
// removals, with keys clustered as body pairs are (few bodies, many partners), so that probe
// runs are long and removals shift entries back across them.
#include "runtime/ppe/pair_table.h"

#include <gtest/gtest.h>

#include <map>
#include <random>

namespace cellphys {
namespace {

using ppe::PairTable;

TEST(PairTable, AgreesWithAnOrderedMapThroughAddsAndRemovals) {
  std::mt19937_64 rng(7);
  for (int round = 0; round < 4; ++round) {
    PairTable<uint64_t> table;
    std::map<uint64_t, uint64_t> ref;
    const uint32_t bodies = round == 0 ? 8 : 200u << round;
    std::uniform_int_distribution<uint32_t> body(0, bodies);
    for (int op = 0; op < 40000; ++op) {
      const uint32_t a = body(rng), b = body(rng);
      const uint64_t key = (uint64_t(std::min(a, b)) << 32) | std::max(a, b);
      switch (rng() % 3) {
        case 0: {
          const auto [v, added] = table.emplace(key, uint64_t(op));
          const bool ref_added = ref.emplace(key, uint64_t(op)).second;
          ASSERT_EQ(added, ref_added) << "key " << key;
          ASSERT_EQ(*v, ref.at(key));
          break;
        }
        case 1: ASSERT_EQ(table.erase(key), ref.erase(key) == 1) << "key " << key; break;
        default: {
          const uint64_t* v = table.find(key);
          const auto it = ref.find(key);
          ASSERT_EQ(v != nullptr, it != ref.end()) << "key " << key;
          if (v) {
            ASSERT_EQ(*v, it->second);
          }
        }
      }
      ASSERT_EQ(table.size(), ref.size());
    }
    // Every entry is reachable by its key, and iteration visits each once.
    std::map<uint64_t, uint64_t> seen(table.begin(), table.end());
    EXPECT_EQ(seen, ref);
    for (const auto& [key, value] : ref) ASSERT_EQ(table.at(key), value);
    table.erase_if([](uint64_t key, uint64_t) { return key % 2 == 0; });
    for (const auto& [key, value] : ref) ASSERT_EQ(table.find(key) != nullptr, key % 2 == 1) << "key " << key;
    table.clear();
    EXPECT_TRUE(table.empty());
    for (const auto& [key, value] : ref) ASSERT_EQ(table.find(key), nullptr);
  }
}

}  // namespace
}  // namespace cellphys
