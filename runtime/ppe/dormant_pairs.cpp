#include "runtime/ppe/dormant_pairs.h"

#include <algorithm>

#include "runtime/base/merge_tail.h"

namespace cellphys::ppe {

namespace {

// Removes the keys of `gone` (ascending) from `keys` (ascending).
void remove_sorted(std::vector<uint64_t>& keys, const std::vector<uint64_t>& gone) {
  auto g = gone.begin();
  size_t out = 0;
  for (uint64_t k : keys) {
    while (g != gone.end() && *g < k) ++g;
    if (g == gone.end() || *g != k) keys[out++] = k;
  }
  keys.resize(out);
}

}  // namespace

void DormantPairs::add(std::vector<uint64_t>& keys) {
  if (keys.empty()) return;
  std::sort(keys.begin(), keys.end());
  merge_sorted_into(by_first_, keys, merged_);
  swapped_.clear();
  for (uint64_t k : keys) swapped_.push_back(swap_halves(k));
  std::sort(swapped_.begin(), swapped_.end());
  merge_sorted_into(by_second_, swapped_, merged_);
}

void DormantPairs::take(const std::vector<uint32_t>& woken, std::vector<uint64_t>& out) {
  if (by_first_.empty()) return;
  taken_.clear();
  for (uint32_t w : woken) {
    if (w == UINT32_MAX) continue;
    const uint64_t lo = uint64_t(w) << 32, hi = (uint64_t(w) + 1) << 32;
    for (auto it = std::lower_bound(by_first_.begin(), by_first_.end(), lo); it != by_first_.end() && *it < hi; ++it)
      taken_.push_back(*it);
    for (auto it = std::lower_bound(by_second_.begin(), by_second_.end(), lo); it != by_second_.end() && *it < hi; ++it)
      taken_.push_back(swap_halves(*it));
  }
  if (taken_.empty()) return;
  std::sort(taken_.begin(), taken_.end());
  taken_.erase(std::unique(taken_.begin(), taken_.end()), taken_.end());
  remove_sorted(by_first_, taken_);
  swapped_.clear();
  for (uint64_t k : taken_) swapped_.push_back(swap_halves(k));
  std::sort(swapped_.begin(), swapped_.end());
  remove_sorted(by_second_, swapped_);
  out.insert(out.end(), taken_.begin(), taken_.end());
}

void DormantPairs::clear() {
  by_first_.clear();
  by_second_.clear();
}

}  // namespace cellphys::ppe
