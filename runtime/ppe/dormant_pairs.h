// Body pairs set aside while both bodies keep still (sleep, or are static), so that a step
// visits only the pairs of what is awake; a body that wakes takes its pairs back. The contact
// memory and the events keep theirs here.
#pragma once
#include <cstdint>
#include <vector>

namespace cellphys::ppe {

class DormantPairs {
 public:
  /// Sets `keys` aside (first << 32 | second, any order; sorted in place).
  void add(std::vector<uint64_t>& keys);
  /// Moves every pair with a body in `woken` (ascending) to the end of `out`, each once.
  void take(const std::vector<uint32_t>& woken, std::vector<uint64_t>& out);
  void clear();
  /// The pairs, ascending by key.
  const std::vector<uint64_t>& keys() const { return by_first_; }

 private:
  std::vector<uint64_t> by_first_;   // ascending
  std::vector<uint64_t> by_second_;  // the keys with their halves swapped, ascending
  std::vector<uint64_t> taken_, swapped_, merged_;
};

inline uint64_t swap_halves(uint64_t k) { return k << 32 | k >> 32; }

}  // namespace cellphys::ppe
