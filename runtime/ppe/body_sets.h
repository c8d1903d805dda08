// Which bodies a step visits, kept as bodies change rather than found by a pass over all of
// them: the awake dynamic bodies in id order, and the counts of the rest. Kept up to date from
// the ids of the bodies that may have changed set (woke, fell asleep, added, removed), so a
// step's cost follows what is awake and what changed, not the size of the world.
#pragma once
#include <cstdint>
#include <vector>

#include "runtime/ppe/body_records.h"

namespace cellphys::ppe {

class AwakeBodies {
 public:
  /// Brings the list up to date with `changed` (ids may repeat); `all` redoes it from every body.
  void update(const std::vector<WorldBody>& bodies, const std::vector<uint32_t>& changed, bool all);
  /// The awake dynamic bodies, ascending.
  const std::vector<uint32_t>& ids() const { return ids_; }
  uint32_t live() const { return live_; }
  uint32_t statics() const { return statics_; }
  /// A pass over every body finds what the list says (for checks).
  bool agrees_with(const std::vector<WorldBody>& bodies) const;

 private:
  enum Kind : uint8_t { dead = 0, fixed = 1, asleep = 2, awake = 3 };
  static Kind kind_of(const WorldBody& b) { return !b.alive ? dead : b.is_static ? fixed : b.awake ? awake : asleep; }
  std::vector<uint32_t> ids_, added_, merged_;
  std::vector<uint8_t> kind_;  // per body slot: what the list counts it as
  uint32_t live_ = 0, statics_ = 0;
};

}  // namespace cellphys::ppe
