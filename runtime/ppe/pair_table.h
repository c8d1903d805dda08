// A map from a body pair's 64-bit key to what the pair keeps, flat: its entries in one array
// and an open-addressed index of them (linear probing, at most half full). Looking a pair up
// costs a multiply and, mostly, one cache line of the index; std::unordered_map's took a
// division and two dependent loads into nodes scattered over the heap, ~8% of a step of a
// world of many contact pairs.
#pragma once
#include <cstdint>
#include <stdexcept>
#include <utility>
#include <vector>

namespace cellphys::ppe {

template <class T>
class PairTable {
 public:
  using Entry = std::pair<uint64_t, T>;

  size_t size() const { return entries_.size(); }
  bool empty() const { return entries_.empty(); }
  void clear() {
    entries_.clear();
    slots_.assign(slots_.size(), Slot{});
  }
  /// The entries, in no particular order (the same for the same calls).
  typename std::vector<Entry>::const_iterator begin() const { return entries_.begin(); }
  typename std::vector<Entry>::const_iterator end() const { return entries_.end(); }

  /// The value of `key`, or null. Stays valid until the next emplace or erase.
  T* find(uint64_t key) {
    if (slots_.empty()) return nullptr;
    for (size_t s = home(key);; s = (s + 1) & mask()) {
      if (slots_[s].index == kEmpty) return nullptr;
      if (slots_[s].key == key) return &entries_[slots_[s].index].second;
    }
  }
  const T* find(uint64_t key) const { return const_cast<PairTable*>(this)->find(key); }
  /// Starts loading where `key` would be: a walk over many keys prefetches some ahead, as
  /// the keys of neighbouring pairs lie far apart in the index.
  void prefetch(uint64_t key) const {
    if (!slots_.empty()) __builtin_prefetch(&slots_[home(key)]);
  }
  const T& at(uint64_t key) const {
    const T* v = find(key);
    if (!v) throw std::out_of_range("PairTable::at: no such key");
    return *v;
  }

  /// Adds `key` with `value` unless it is there; its value and whether it was added.
  std::pair<T*, bool> emplace(uint64_t key, const T& value) {
    if (2 * (entries_.size() + 1) > slots_.size()) grow();
    size_t s = home(key);
    for (; slots_[s].index != kEmpty; s = (s + 1) & mask())
      if (slots_[s].key == key) return {&entries_[slots_[s].index].second, false};
    slots_[s] = Slot{key, uint32_t(entries_.size())};
    entries_.emplace_back(key, value);
    return {&entries_.back().second, true};
  }

  /// Removes `key`; whether it was there. The last entry takes the removed one's place.
  bool erase(uint64_t key) {
    if (slots_.empty()) return false;
    size_t s = home(key);
    for (; slots_[s].key != key || slots_[s].index == kEmpty; s = (s + 1) & mask())
      if (slots_[s].index == kEmpty) return false;
    const uint32_t index = slots_[s].index;
    if (index + 1 != entries_.size()) {
      entries_[index] = std::move(entries_.back());
      slot_of(entries_[index].first).index = index;
    }
    entries_.pop_back();
    // Backward-shift deletion: each later entry of the run moves into the hole unless its
    // home lies after the hole, so no lookup meets an empty slot before its key.
    for (size_t j = (s + 1) & mask(); slots_[j].index != kEmpty; j = (j + 1) & mask()) {
      if (((j - home(slots_[j].key)) & mask()) >= ((j - s) & mask())) {
        slots_[s] = slots_[j];
        s = j;
      }
    }
    slots_[s] = Slot{};
    return true;
  }

  /// Removes every entry for which pred(key, value) holds.
  template <class Pred>
  void erase_if(Pred pred) {
    std::vector<uint64_t> gone;
    for (const Entry& e : entries_)
      if (pred(e.first, e.second)) gone.push_back(e.first);
    for (uint64_t key : gone) erase(key);
  }

 private:
  static constexpr uint32_t kEmpty = 0xffffffffu;
  struct Slot {
    uint64_t key = 0;
    uint32_t index = kEmpty;
  };
  size_t mask() const { return slots_.size() - 1; }
  // Fibonacci hashing: the top bits of the key times 2^64 / phi, so both bodies' ids spread.
  size_t home(uint64_t key) const { return size_t((key * 0x9e3779b97f4a7c15ull) >> shift_); }
  Slot& slot_of(uint64_t key) {
    size_t s = home(key);
    while (slots_[s].key != key || slots_[s].index == kEmpty) s = (s + 1) & mask();
    return slots_[s];
  }
  void grow() {
    const size_t n = slots_.empty() ? 64 : 2 * slots_.size();
    shift_ = 64;
    for (size_t m = n; m > 1; m >>= 1) --shift_;
    slots_.assign(n, Slot{});
    for (uint32_t i = 0; i < entries_.size(); ++i) {
      size_t s = home(entries_[i].first);
      while (slots_[s].index != kEmpty) s = (s + 1) & mask();
      slots_[s] = Slot{entries_[i].first, i};
    }
  }

  std::vector<Entry> entries_;
  std::vector<Slot> slots_;  // a power of two of them, or none
  int shift_ = 64;
};

}  // namespace cellphys::ppe
