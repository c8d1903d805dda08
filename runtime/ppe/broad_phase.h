// Broad and mid phase: bounding boxes culled against the simulated region, then a 1-D sort
// and sweep along the axis of largest spread, the order kept between steps so insertion
// sort runs on nearly sorted data.
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
  /// Overlapping pairs (i < j) among slots with a box, except pairs where neither is awake.
  /// Output sorted, so it does not depend on the sort order kept between steps.
  void find_pairs(const std::vector<Aabb>& boxes, const std::vector<BoxKind>& kind,
                  std::vector<std::pair<uint32_t, uint32_t>>& pairs);
  int axis() const { return axis_; }
  uint64_t swaps() const { return swaps_; }

 private:
  std::vector<uint32_t> order_;
  int axis_ = -1;
  uint64_t swaps_ = 0;
};

/// Box of a slot intersects the region.
bool inside_region(const Aabb& box, const float (&min)[3], const float (&max)[3]);

}  // namespace cellphys::ppe
