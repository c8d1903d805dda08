#include "runtime/ppe/broad_phase.h"

#include <algorithm>

namespace cellphys::ppe {

bool inside_region(const Aabb& box, const float (&min)[3], const float (&max)[3]) {
  for (int k = 0; k < 3; ++k)
    if (box.max[k] < min[k] || box.min[k] > max[k]) return false;
  return true;
}

void SweepAndPrune::find_pairs(const std::vector<Aabb>& boxes, const std::vector<BoxKind>& kind,
                               const std::vector<uint32_t>& ids, std::vector<std::pair<uint32_t, uint32_t>>& pairs) {
  // Axis of largest spread of the box centres.
  double sum[3] = {}, sq[3] = {};
  int count = 0;
  for (uint32_t i : ids) {
    if (kind[i] != BoxKind::awake) continue;
    ++count;
    for (int k = 0; k < 3; ++k) {
      const double c = 0.5 * (double(boxes[i].min[k]) + boxes[i].max[k]);
      sum[k] += c;
      sq[k] += c * c;
    }
  }
  int axis = 0;
  double best = -1;
  for (int k = 0; k < 3; ++k) {
    const double var = count ? sq[k] / count - (sum[k] / count) * (sum[k] / count) : 0.0;
    if (var > best * 1.2) best = var, axis = k;  // hysteresis: do not flip axes on noise
  }
  if (axis_ >= 0 && axis != axis_) {
    double cur = count ? sq[axis_] / count - (sum[axis_] / count) * (sum[axis_] / count) : 0.0;
    if (best < 1.5 * cur) axis = axis_;
  }
  // Keep the previous order; drop slots no longer awake in the region, append new ones.
  if (in_order_.size() < boxes.size()) in_order_.resize(boxes.size(), 0);
  size_t w = 0;
  for (uint32_t s : order_) {
    if (s < kind.size() && kind[s] == BoxKind::awake) order_[w++] = s;
    else in_order_[s] = 0;
  }
  order_.resize(w);
  for (uint32_t i : ids)
    if (kind[i] == BoxKind::awake && !in_order_[i]) in_order_[i] = 1, order_.push_back(i);
  if (axis != axis_) {
    axis_ = axis;
    std::sort(order_.begin(), order_.end(), [&](uint32_t a, uint32_t b) {
      return boxes[a].min[axis] < boxes[b].min[axis] || (boxes[a].min[axis] == boxes[b].min[axis] && a < b);
    });
  } else {
    // insertion sort: linear on the nearly sorted order of the last step
    for (size_t i = 1; i < order_.size(); ++i) {
      const uint32_t s = order_[i];
      const float key = boxes[s].min[axis];
      size_t j = i;
      while (j > 0 && (boxes[order_[j - 1]].min[axis] > key ||
                       (boxes[order_[j - 1]].min[axis] == key && order_[j - 1] > s))) {
        order_[j] = order_[j - 1];
        --j;
        ++swaps_;
      }
      order_[j] = s;
    }
  }
  const int o1 = (axis + 1) % 3, o2 = (axis + 2) % 3;
  for (size_t i = 0; i < order_.size(); ++i) {
    const uint32_t a = order_[i];
    const Aabb& A = boxes[a];
    for (size_t j = i + 1; j < order_.size(); ++j) {
      const uint32_t b = order_[j];
      const Aabb& B = boxes[b];
      if (B.min[axis] > A.max[axis]) break;
      if (B.min[o1] > A.max[o1] || B.max[o1] < A.min[o1] || B.min[o2] > A.max[o2] || B.max[o2] < A.min[o2]) continue;
      pairs.emplace_back(std::min(a, b), std::max(a, b));
    }
  }
}

}  // namespace cellphys::ppe
