// How deep the boxes of a scene overlap each other and its planes, from the bodies' states
// (any engine's, through the peer interface): what cellphys_bench's situations and the
// overlap map measure. Other shapes are not measured.
#pragma once
#include <vector>

#include "bench/peers/peer.h"

namespace cellphys::bench {

class Overlaps {
 public:
  explicit Overlaps(const scene::SceneDesc& scene);
  /// Overlap depth of bodies a and b: for two boxes the least overlap of their projections on
  /// the 15 separating axes, for a box and a plane how far the box's lowest corner is inside
  /// it. At most 0 when they are apart (or one is neither a box nor a plane).
  double depth(size_t a, size_t b, const std::vector<State>& s) const;
  /// The deepest overlap of any pair of boxes or of a box and a plane; 0 when none overlaps.
  double deepest(const std::vector<State>& s) const;
  /// What each body rests on at the start: the nearest box below it on its vertical line,
  /// else the first plane, else -1 (also for planes and static bodies).
  const std::vector<int>& below() const { return below_; }

 private:
  const scene::SceneDesc& scene_;
  std::vector<const scene::ShapeSpec*> shape_;  // per body
  std::vector<size_t> boxes_, planes_;
  std::vector<int> below_;
};

}  // namespace cellphys::bench
