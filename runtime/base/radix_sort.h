// Sorting in linear time: a least-significant-digit radix sort over only the bits the keys
// use, in a few passes over them. Values with equal keys are equal, so the order is the one
// std::sort gives: std::sort of the broad phase's 28,000 pairs in no particular order took 46 ns a pair,
// and of a step's 900 islands by size, with the size looked up at each comparison, 35 us.
#pragma once
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

namespace cellphys {

/// How many low bits the keys OR-ed together into `any` use: the width of a radix sort's key.
inline int bits_used(uint64_t any) {
  int bits = 0;
  while (bits < 64 && (any >> bits) != 0) ++bits;
  return bits;
}

namespace radix_detail {

// Sorts `values` ascending by key(value), of `bits` significant bits, through `buffer`. A
// digit has about as many buckets as there are values, up to 2^11: clearing and summing 2,048
// counters a pass cost a sort of a hundred values more than the values did.
template <class T, class Key>
void sort_by_key(std::vector<T>& values, std::vector<T>& buffer, int bits, Key key) {
  constexpr int kMostDigit = 11;
  const int digit = std::min(kMostDigit, std::max(4, bits_used(values.size()) - 1));
  const size_t buckets = size_t(1) << digit;
  buffer.resize(values.size());
  std::vector<T>* from = &values;
  std::vector<T>* to = &buffer;
  uint32_t count[size_t(1) << kMostDigit];
  for (int shift = 0; shift < bits; shift += digit) {
    for (size_t b = 0; b < buckets; ++b) count[b] = 0;
    for (const T& v : *from) ++count[(key(v) >> shift) & (buckets - 1)];
    uint32_t sum = 0;
    for (size_t b = 0; b < buckets; ++b) {
      const uint32_t c = count[b];
      count[b] = sum, sum += c;
    }
    for (const T& v : *from) (*to)[count[(key(v) >> shift) & (buckets - 1)]++] = v;
    std::swap(from, to);
  }
  if (from != &values) values.swap(buffer);
}

// Below this many values the counting does not repay itself.
constexpr size_t kFewValues = 64;

template <class T>
void insertion_sort(std::vector<T>& v) {
  for (size_t i = 1; i < v.size(); ++i)
    for (size_t j = i; j > 0 && v[j] < v[j - 1]; --j) std::swap(v[j], v[j - 1]);
}

}  // namespace radix_detail

/// Sorts `pairs` ascending by (first, second); `buffer` is scratch (resized as needed).
inline void radix_sort_pairs(std::vector<std::pair<uint32_t, uint32_t>>& pairs,
                             std::vector<std::pair<uint32_t, uint32_t>>& buffer) {
  if (pairs.size() < radix_detail::kFewValues) return radix_detail::insertion_sort(pairs);
  uint32_t any_first = 0, any_second = 0;
  for (const auto& p : pairs) any_first |= p.first, any_second |= p.second;
  const int bits_second = bits_used(any_second), bits_first = bits_used(any_first);
  // The key: first above second, in as few bits as they need.
  radix_detail::sort_by_key(pairs, buffer, bits_first + bits_second,
                            [&](const std::pair<uint32_t, uint32_t>& p) { return uint64_t(p.first) << bits_second | p.second; });
}

/// Sorts 64-bit `keys` ascending; `buffer` is scratch (resized as needed).
inline void radix_sort_keys(std::vector<uint64_t>& keys, std::vector<uint64_t>& buffer) {
  if (keys.size() < radix_detail::kFewValues) return radix_detail::insertion_sort(keys);
  uint64_t any = 0;
  for (uint64_t k : keys) any |= k;
  radix_detail::sort_by_key(keys, buffer, bits_used(any), [](uint64_t k) { return k; });
}

}  // namespace cellphys
