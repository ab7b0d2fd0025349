#include "lblight/solve/convergence.h"

#include <algorithm>
#include <cmath>

namespace lblight {

double ConvergenceMonitor::unit_roundoff(Precision p) {
  switch (p) {
    case Precision::Float64: return 1.1e-16;
    case Precision::Float16: return 4.9e-4;
    default: return 6.0e-8;
  }
}

double ConvergenceMonitor::round_off_for(Precision p) {
  switch (p) {
    case Precision::Float64: return 1e-13;
    case Precision::Float16: return 2e-3;
    default: return 2e-6;
  }
}

namespace {
// Slope of log(y) against the check index over the last n entries of ys.
double log_slope(const std::vector<double>& ys, std::size_t n) {
  const std::size_t first = ys.size() - n;
  double sx = 0, sy = 0, sxx = 0, sxy = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const double x = static_cast<double>(i), y = std::log(ys[first + i]);
    sx += x;
    sy += y;
    sxx += x * x;
    sxy += x * y;
  }
  const double dn = static_cast<double>(n);
  return (dn * sxy - sx * sy) / (dn * sxx - sx * sx);
}
}  // namespace

double ConvergenceMonitor::tail_estimate(double CheckPoint::*change, double floor, double* ratio) const {
  // Trailing checks with the same interval as the last one (ratios need equal intervals).
  std::vector<double> ys;
  const int interval = history_.back().interval;
  for (auto it = history_.rbegin(); it != history_.rend() && it->interval == interval && ys.size() < 8; ++it)
    ys.insert(ys.begin(), (*it).*change);
  const std::size_t n = ys.size();
  const double now = ys.back();
  if (!std::isfinite(now)) return kUnknown;
  // float16: no change at all is its rounded iteration's fixed point, the rounding floor away
  if (now == 0.0) return half_storage_ ? std::max(floor, rounding_floor(interval)) : floor;
  bool positive = n >= (accelerated_ ? 4 : 5);
  for (double y : ys) positive = positive && y > 0.0;
  if (positive && accelerated_ && now > round_off_) {
    const double r = std::max({ys[n - 1] / ys[n - 2], ys[n - 2] / ys[n - 3], ys[n - 3] / ys[n - 4]});
    if (r < kAcceleratedRatio) {
      if (ratio) *ratio = r;
      return std::max(2.0 * now * r / (1.0 - r), floor);
    }
  }
  positive = positive && n >= 5;  // the settled-ratio test below needs four ratios
  if (positive) {
    const double r1 = ys[n - 1] / ys[n - 2], r2 = ys[n - 2] / ys[n - 3], r3 = ys[n - 3] / ys[n - 4],
                 r4 = ys[n - 4] / ys[n - 5];
    const double r = std::max(r1, std::exp(log_slope(ys, std::min<std::size_t>(n, 6))));
    // Trust the geometric tail only once the ratio has settled: while fast modes are still dying
    // the ratio climbs toward the slowest one and any extrapolation would be too optimistic.
    // Changes that shrink this regularly are signal, however small (a slow mode of thin
    // fringes moves by 1e-7 per check); rounding noise does not keep a steady ratio.
    const double gap = 1.0 - r;
    // Four ratios must agree, also in absolute terms: at the leafy plant's light front (report,
    // docs/accuracy.md) ratios of 0.44, 0.36, 0.23, 0.29 passed a test relative to the large gap
    // alone and gave an estimate below the true error.
    if (r < 1.0 && std::fabs(r1 - r2) <= std::min(0.1 * gap, 0.02) && std::fabs(r2 - r3) <= std::min(0.2 * gap, 0.04) &&
        std::fabs(r3 - r4) <= std::min(0.3 * gap, 0.06)) {
      if (ratio) *ratio = r;
      // Factor 2: even a settled ratio keeps creeping up while the last fast modes fade.
      return std::max(2.0 * now * r / gap, floor);
    }
  }
  // Irregular changes at the noise level: the iteration has stalled on rounding, as converged as
  // the precision allows; the rounding floor (record()) says how far that is from the fixed point.
  // An accelerated iteration must have shown its contraction first (its cycles are few, and a
  // stagnating one also makes small changes).
  if (now <= round_off_ && !(accelerated_ && settled_q_ < 0)) {
    // float16's noise level is high enough for a transient's signal to fall below it (a plant at
    // 2N steps: changes 1.3e-2, 5.5e-3, 3.0e-3, 1.6e-3 per check, the same in float32, true error
    // 7e-3): stalled only once the changes stop falling or reach the rounded fixed point (0).
    if (half_storage_ && !changes_stopped_falling(ys)) return kUnknown;
    return std::max({round_off_, floor, rounding_floor(interval)});
  }
  return kUnknown;  // not contracting yet (light still spreading) or the ratio is still moving
}

bool ConvergenceMonitor::changes_stopped_falling(const std::vector<double>& ys) {
  const std::size_t n = std::min<std::size_t>(ys.size(), 6);
  if (n < 4) return false;
  for (std::size_t i = ys.size() - n; i < ys.size(); ++i)
    if (ys[i] == 0.0) return true;  // a check that changed nothing: the rounded iteration's fixed point
  return std::exp(log_slope(ys, n)) >= kStalledRatio;
}

double ConvergenceMonitor::rounding_floor(int interval) const {
  const double q = settled_q_ >= 0 ? settled_q_ : q_hint_;
  if (q < 0) return 0.0;
  const double gap = std::max(1e-12, 1.0 - q);
  // 5 u per step, amplified by 1 / (1 - q) of the last settled contraction (header comment).
  if (!half_storage_) return 5.0 * unit_ / gap;
  // float16 storage: its rounding, incoherent from step to step (docs/accuracy.md, "float16
  // storage against float32"); and a mode contracting by q whose changes, up to the noise level
  // per check, cannot be told from rounding: its tail, doubled as a settled tail is.
  const double r = std::pow(q, std::max(1, interval));
  return std::max(unit_ / std::sqrt(gap), 2.0 * round_off_ * r / std::max(1e-12, 1.0 - r));
}

void ConvergenceMonitor::record(int step, int interval, double seconds, const Residual& r) {
  CheckPoint c;
  c.step = step;
  c.interval = interval;
  c.seconds = seconds;
  c.change_l2 = r.total_sq > 0 ? std::sqrt(r.diff_sq / r.total_sq) : (r.diff_sq > 0 ? 1.0 : 0.0);
  c.change_max = r.total_max > 0 ? r.diff_max / r.total_max : (r.diff_max > 0 ? 1.0 : 0.0);
  c.deficit_l2 = r.total_sq > 0 ? std::sqrt(r.deficit_sq / r.total_sq) : 0.0;
  const double deficit_max = r.total_max > 0 ? r.deficit_max / r.total_max : 0.0;
  if (!r.finite) c.change_l2 = c.change_max = kUnknown;
  history_.push_back(c);
  double ratio = -1;
  history_.back().error_estimate = tail_estimate(&CheckPoint::change_l2, c.deficit_l2, &ratio);
  history_.back().error_estimate_max = tail_estimate(&CheckPoint::change_max, deficit_max, nullptr);
  if (ratio > 0 && interval > 0) settled_q_ = std::pow(ratio, 1.0 / interval);
}

}  // namespace lblight
