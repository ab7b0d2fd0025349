// How far an array of totals lies from a reference: the relative L2 distance
// ||got - ref|| / ||ref|| and the relative max distance max |got - ref| / max |ref|, summed in
// double; 0 when the reference is all zero. Used to report storage precisions against float32.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <vector>

namespace lblight {

struct RelativeGap {
  double l2 = 0, max = 0;
};

template <typename Got, typename Ref>
RelativeGap relative_gap(const std::vector<Got>& got, const std::vector<Ref>& ref) {
  double diff_sq = 0, ref_sq = 0, diff_max = 0, ref_max = 0;
  for (std::size_t i = 0; i < ref.size(); ++i) {
    const double d = static_cast<double>(got[i]) - static_cast<double>(ref[i]);
    diff_sq += d * d;
    ref_sq += static_cast<double>(ref[i]) * static_cast<double>(ref[i]);
    diff_max = std::max(diff_max, std::fabs(d));
    ref_max = std::max(ref_max, std::fabs(static_cast<double>(ref[i])));
  }
  return {ref_sq > 0 ? std::sqrt(diff_sq / ref_sq) : 0.0, ref_max > 0 ? diff_max / ref_max : 0.0};
}

}  // namespace lblight
