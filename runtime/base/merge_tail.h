// Merging a sorted vector with the sorted run appended to it, through a buffer the caller
// keeps: std::inplace_merge takes a buffer from the heap each time, and a step that merges
// new keys into its sorted memories (touching pairs, dormant pairs, awake bodies) would
// allocate every time something began, slept or woke.
#pragma once
#include <algorithm>
#include <cstddef>
#include <vector>

namespace cellphys {

/// v[0, old) and v[old, end), each sorted, merged into one sorted run, equal elements of the
/// first run first (as std::inplace_merge orders them). `buffer` is scratch: its storage and
/// v's are exchanged, so neither allocates once both have grown.
template <class T>
void merge_tail(std::vector<T>& v, size_t old, std::vector<T>& buffer) {
  if (old == 0 || old == v.size()) return;
  buffer.resize(v.size());
  std::merge(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(old), v.begin() + static_cast<std::ptrdiff_t>(old), v.end(),
             buffer.begin());
  v.swap(buffer);
}

/// The sorted `more` merged into the sorted `v`, through `buffer` as merge_tail.
template <class T>
void merge_sorted_into(std::vector<T>& v, const std::vector<T>& more, std::vector<T>& buffer) {
  const size_t old = v.size();
  v.insert(v.end(), more.begin(), more.end());
  merge_tail(v, old, buffer);
}

}  // namespace cellphys
