#include "runtime/ppe/broad_phase.h"

#include <algorithm>
#include <limits>

#include "runtime/base/simd.h"

namespace cellphys::ppe {

void SweptBoxes::resize(size_t n) {
  for (std::vector<float>* v : {&lo_, &hi_, &min1_, &max1_, &min2_, &max2_}) v->resize(n + kBlock);
  // past the last box: a block that starts there is out of every band
  std::fill(lo_.begin() + ptrdiff_t(n), lo_.end(), std::numeric_limits<float>::infinity());
}

uint32_t SweptBoxes::hits(size_t j, const SweptBox& a, uint32_t* in_band) const {
#if defined(CELLPHYS_SIMD_PATH_AVX512)
  const __mmask16 band = _mm512_cmp_ps_mask(_mm512_loadu_ps(&lo_[j]), _mm512_set1_ps(a.hi), _CMP_LE_OQ);
  __mmask16 apart = _mm512_cmp_ps_mask(_mm512_loadu_ps(&min1_[j]), _mm512_set1_ps(a.max1), _CMP_GT_OQ);
  apart |= _mm512_cmp_ps_mask(_mm512_loadu_ps(&max1_[j]), _mm512_set1_ps(a.min1), _CMP_LT_OQ);
  apart |= _mm512_cmp_ps_mask(_mm512_loadu_ps(&min2_[j]), _mm512_set1_ps(a.max2), _CMP_GT_OQ);
  apart |= _mm512_cmp_ps_mask(_mm512_loadu_ps(&max2_[j]), _mm512_set1_ps(a.min2), _CMP_LT_OQ);
  *in_band = band;
  return band & ~uint32_t(apart) & kFullBlock;
#elif defined(CELLPHYS_SIMD_PATH_AVX2)
  uint32_t band = 0, apart = 0;
  for (int h = 0; h < 2; ++h) {
    const size_t k = j + 8 * size_t(h);
    const __m256 in = _mm256_cmp_ps(_mm256_loadu_ps(&lo_[k]), _mm256_set1_ps(a.hi), _CMP_LE_OQ);
    __m256 out = _mm256_cmp_ps(_mm256_loadu_ps(&min1_[k]), _mm256_set1_ps(a.max1), _CMP_GT_OQ);
    out = _mm256_or_ps(out, _mm256_cmp_ps(_mm256_loadu_ps(&max1_[k]), _mm256_set1_ps(a.min1), _CMP_LT_OQ));
    out = _mm256_or_ps(out, _mm256_cmp_ps(_mm256_loadu_ps(&min2_[k]), _mm256_set1_ps(a.max2), _CMP_GT_OQ));
    out = _mm256_or_ps(out, _mm256_cmp_ps(_mm256_loadu_ps(&max2_[k]), _mm256_set1_ps(a.min2), _CMP_LT_OQ));
    band |= uint32_t(_mm256_movemask_ps(in)) << (8 * h);
    apart |= uint32_t(_mm256_movemask_ps(out)) << (8 * h);
  }
  *in_band = band;
  return band & ~apart;
#else
  uint32_t band = 0, apart = 0;
  for (size_t k = 0; k < kBlock; ++k) {
    band |= uint32_t(lo_[j + k] <= a.hi) << k;
    apart |= uint32_t((min1_[j + k] > a.max1) | (max1_[j + k] < a.min1) | (min2_[j + k] > a.max2) |
                      (max2_[j + k] < a.min2))
             << k;
  }
  *in_band = band;
  return band & ~apart;
#endif
}

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
  // The boxes copied in sweep order, one array per bound, so the sweep reads memory in sequence
  // and tests a block of candidates at once: in a pile every box has a hundred or more
  // candidates in its band along the axis (a 5,050-box pyramid standing in the x-z plane), and
  // gathering each candidate's box by its slot was most of the sweep's time. The pairs come
  // out in the order the one-at-a-time sweep found them.
  const int o1 = (axis + 1) % 3, o2 = (axis + 2) % 3;
  const size_t n = order_.size();
  swept_.resize(n);
  for (size_t i = 0; i < n; ++i) {
    const Aabb& b = boxes[order_[i]];
    swept_.set(i, b.min[axis], b.max[axis], b.min[o1], b.max[o1], b.min[o2], b.max[o2]);
  }
  for (size_t i = 0; i < n; ++i) {
    const SweptBox A = swept_.box(i);
    for (size_t j = i + 1; j < n; j += SweptBoxes::kBlock) {
      uint32_t in_band = 0;
      uint32_t hits = swept_.hits(j, A, &in_band);
      if (n - j < SweptBoxes::kBlock) {  // the last block: its padding is past every finite band,
        const uint32_t boxes_left = (1u << (n - j)) - 1;  // not past a box reaching to +inf
        hits &= boxes_left;
        in_band &= boxes_left;
      }
      for (; hits; hits &= hits - 1) {
        const uint32_t a = order_[i], b = order_[j + uint32_t(__builtin_ctz(hits))];
        pairs.emplace_back(std::min(a, b), std::max(a, b));
      }
      if (in_band != SweptBoxes::kFullBlock) break;  // sorted along the axis: the band ended here
    }
  }
}

}  // namespace cellphys::ppe
