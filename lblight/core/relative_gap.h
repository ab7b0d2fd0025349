// How far an array of totals lies from a reference: the relative L2 distance
// ||got - ref|| / ||ref|| and the relative max distance max |got - ref| / max |ref|, summed in
// double; 0 when the reference is all zero. Used to report storage precisions against float32.
// And the pointwise form, max |got - ref| / |ref|, for comparing bakes and in tests.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <vector>

namespace lblight {

// worst = max(worst, v), except that NaN sticks: std::max(worst, NaN) keeps worst, and once
// worst is NaN every later value would replace it, so a comparison built on either would pass a
// broken result.
inline void keep_worst(double& worst, double v) {
  if (std::isnan(worst)) return;
  if (!(v <= worst)) worst = v;
}

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
    keep_worst(diff_max, std::fabs(d));
    ref_max = std::max(ref_max, std::fabs(static_cast<double>(ref[i])));
  }
  return {ref_sq > 0 ? std::sqrt(diff_sq / ref_sq) : 0.0, ref_max > 0 ? diff_max / ref_max : 0.0};
}

// max |v_i|, NaN when any value is NaN.
template <typename V>
double peak_magnitude(const V& v) {
  double p = 0;
  for (auto x : v) {
    const double a = std::fabs(static_cast<double>(x));
    keep_worst(p, a);
  }
  return p;
}

// The largest |got_i - ref_i| / max(|ref_i|, floor): each value's difference relative to the
// reference value, with values below `floor` measured against the floor. NaN in either makes it
// NaN (a comparison that skipped NaN would pass a broken result).
template <typename Ref, typename Got>
double max_relative_difference(const std::vector<Ref>& ref, const std::vector<Got>& got, double floor = 1e-30) {
  double worst = 0;
  for (std::size_t i = 0; i < ref.size(); ++i) {
    const double r = static_cast<double>(ref[i]);
    const double d = std::fabs(static_cast<double>(got[i]) - r) / std::max(std::fabs(r), floor);
    keep_worst(worst, d);
  }
  return worst;
}

}  // namespace lblight
