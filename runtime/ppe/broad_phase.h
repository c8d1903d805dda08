// Broad and mid phase: bounding boxes culled against the simulated region; the awake boxes
// sorted and swept along the axis of their largest spread (the order kept between steps, so
// insertion sort runs on nearly sorted data), each against the tree of the boxes that keep
// still (runtime/ppe/box_tree.h).
#pragma once
#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

namespace cellphys::ppe {

struct Aabb {
  float min[3];
  float max[3];
};

enum class BoxKind : uint8_t { none = 0, awake = 1, asleep = 2, fixed = 3 };

/// A box's bounds along the sweep axis (lo, hi) and the other two.
struct SweptBox {
  float lo, hi, min1, max1, min2, max2;
};

/// The awake boxes in sweep order, one array per bound, padded so a block may start anywhere
/// up to the end.
class SweptBoxes {
 public:
  static constexpr size_t kBlock = 16;
  static constexpr uint32_t kFullBlock = 0xFFFFu;
  void resize(size_t n);
  void set(size_t i, float lo, float hi, float min1, float max1, float min2, float max2) {
    lo_[i] = lo, hi_[i] = hi, min1_[i] = min1, max1_[i] = max1, min2_[i] = min2, max2_[i] = max2;
  }
  SweptBox box(size_t i) const { return {lo_[i], hi_[i], min1_[i], max1_[i], min2_[i], max2_[i]}; }
  /// Of boxes j .. j + kBlock - 1: bit k of *in_band set when box j + k starts within a's span
  /// along the axis, and of the result when it also overlaps a across it.
  uint32_t hits(size_t j, const SweptBox& a, uint32_t* in_band) const;

 private:
  std::vector<float> lo_, hi_, min1_, max1_, min2_, max2_;
};

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
  SweptBoxes swept_;
  std::vector<uint8_t> in_order_;  // per slot
  int axis_ = -1;
  uint64_t swaps_ = 0;
};

/// Box of a slot intersects the region.
bool inside_region(const Aabb& box, const float (&min)[3], const float (&max)[3]);

}  // namespace cellphys::ppe
