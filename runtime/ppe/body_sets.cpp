#include "runtime/ppe/body_sets.h"

#include <algorithm>

#include "runtime/base/merge_tail.h"

namespace cellphys::ppe {

void AwakeBodies::update(const std::vector<WorldBody>& bodies, const std::vector<uint32_t>& changed, bool all) {
  const uint32_t n = static_cast<uint32_t>(bodies.size());
  if (all) {
    ids_.clear();
    kind_.assign(n, dead);
    live_ = statics_ = 0;
    for (uint32_t i = 0; i < n; ++i) {
      kind_[i] = kind_of(bodies[i]);
      live_ += kind_[i] != dead;
      statics_ += kind_[i] == fixed;
      if (kind_[i] == awake) ids_.push_back(i);
    }
    return;
  }
  if (kind_.size() < n) kind_.resize(n, dead);
  added_.clear();
  bool dropped = false;
  for (uint32_t id : changed) {
    const Kind now = kind_of(bodies[id]), was = Kind(kind_[id]);
    if (now == was) continue;
    live_ += (now != dead) - (was != dead);
    statics_ += (now == fixed) - (was == fixed);
    if (now == awake) added_.push_back(id);
    dropped = dropped || was == awake;
    kind_[id] = now;
  }
  if (dropped) ids_.erase(std::remove_if(ids_.begin(), ids_.end(), [&](uint32_t id) { return kind_[id] != awake; }), ids_.end());
  if (added_.empty()) return;
  // (each id's kind moves once, from what the list had to what the body is now: no repeats)
  std::sort(added_.begin(), added_.end());
  const size_t old = ids_.size();
  ids_.insert(ids_.end(), added_.begin(), added_.end());
  merge_tail(ids_, old, merged_);
}

bool AwakeBodies::agrees_with(const std::vector<WorldBody>& bodies) const {
  // checked every step of a debug build, without allocating (a warm step allocates nothing)
  uint32_t live = 0, statics = 0;
  size_t next = 0;
  for (uint32_t i = 0; i < bodies.size(); ++i) {
    const Kind k = kind_of(bodies[i]);
    live += k != dead;
    statics += k == fixed;
    if (k == awake && (next == ids_.size() || ids_[next++] != i)) return false;
  }
  return next == ids_.size() && live == live_ && statics == statics_;
}

}  // namespace cellphys::ppe
