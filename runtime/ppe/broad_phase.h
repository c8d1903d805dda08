// Broad and mid phase: bounding boxes culled against the simulated region; the awake boxes
// sorted and swept along the axis of their largest spread (the order kept between steps, so
// insertion sort runs on nearly sorted data), each against the tree of the boxes that keep
// still (runtime/ppe/box_tree.h).
#pragma once
#include <cstdint>
#include <utility>
#include <vector>

namespace cellphys::ppe {

struct Aabb {
  float min[3];
  float max[3];
};

enum class BoxKind : uint8_t { none = 0, awake = 1, asleep = 2, fixed = 3 };

class SweepAndPrune {
 public:
  /// Appends the overlapping pairs (i < j) among the slots of `ids` whose kind is awake, in no
  /// particular order.
  void find_pairs(const std::vector<Aabb>& boxes, const std::vector<BoxKind>& kind, const std::vector<uint32_t>& ids,
                  std::vector<std::pair<uint32_t, uint32_t>>& pairs);
  int axis() const { return axis_; }
  uint64_t swaps() const { return swaps_; }

 private:
  std::vector<uint32_t> order_;
  std::vector<uint8_t> in_order_;  // per slot
  int axis_ = -1;
  uint64_t swaps_ = 0;
};

/// Box of a slot intersects the region.
bool inside_region(const Aabb& box, const float (&min)[3], const float (&max)[3]);

}  // namespace cellphys::ppe
