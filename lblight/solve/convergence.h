// Error estimate for the plain LB iteration f <- A f + b (docs/model.md sec. 5). Totals are measured
// every K steps. Once the changes shrink geometrically with ratio r per interval, the distance
// to the fixed point is the tail of that series: change * r / (1 - r). The estimate is given only
// once the ratio has settled (successive ratios agree to a fraction of 1 - r): while faster modes
// are dying the ratio climbs and any extrapolation would be optimistic. r is the larger of the
// last ratio and a log-linear fit over the last checks (robust to float noise), and the tail is
// doubled as a margin for the ratio's remaining creep. Changes at the round-off level of the
// storage precision, when they no longer shrink regularly, count as converged to that level.
// The estimate is never below the f_0 reservoir deficit (backend.h, Residual), which decays too
// slowly to show in the changes. Once stalled at the noise level, it is also never below the
// rounding floor of the storage precision: each step rounds at a few units u, and the
// iteration's fixed point moves by that amount times 1 / (1 - q), q the per-step contraction
// (measured: float32 on a 22^3 dense cube stalls at 1.3e-5 = 200 u with 1/(1-q) = 51). float16
// storage with float32 arithmetic rounds only what it stores, and those errors do not add up
// coherently (measured 1.6 u on a 48^3 dense cube where 5 u / (1 - q) is 800 u): its floor is
// u / sqrt(1 - q), or the tail of a slow mode whose changes hide below the checks' noise level,
// whichever is larger (rounding_floor); and float16 counts as stalled only once its changes
// below the noise level stop falling (a transient's signal can be that small). While the changes
// still shrink with a settled ratio they are signal and the tail estimate holds (a procedural
// cloud's thin fringe: changes of 1e-7 per check, true error still falling).
#pragma once

#include <limits>
#include <vector>

#include "lblight/backend/backend.h"

namespace lblight {

struct CheckPoint {
  int step = 0;
  int interval = 0;             // steps since the previous check
  double seconds = 0;
  double change_l2 = 0;         // ||T_t - T_{t-K}||_2 / ||T_t||_2 over interior nodes
  double change_max = 0;        // max |T_t - T_{t-K}| / max |T_t|
  double error_estimate = 0;    // estimated relative L2 distance to steady state (inf = unknown)
  double error_estimate_max = 0;  // the same in the max norm
  double deficit_l2 = 0;        // f_0 reservoir still to fill, relative L2 (Residual::deficit_sq)
};

class ConvergenceMonitor {
 public:
  // round_off: relative change that is pure float noise for this storage precision.
  // q_hint: a rough per-step contraction from the physics (plan.h, StepPolicy::decay_hint) for the
  // rounding floor until the iteration shows its own; after a Krylov solve the verification
  // checks see only noise-level changes and have nothing else to go on. < 0: none.
  explicit ConvergenceMonitor(Precision p, double q_hint = -1)
      : round_off_(round_off_for(p)), unit_(unit_roundoff(p)), half_storage_(p == Precision::Float16), q_hint_(q_hint) {}

  // For an accelerated iteration (solve/dsa.h), whose changes per cycle shrink fast but with
  // ratios that wander between several modes: once the last three ratios are all below
  // kAcceleratedRatio, the tail is bounded with the largest of them (a series whose ratios stay
  // below r sums to at most change * r / (1 - r)), doubled as for the plain iteration.
  static ConvergenceMonitor accelerated(Precision p, double q_hint) {
    ConvergenceMonitor m(p, q_hint);
    m.accelerated_ = true;
    return m;
  }
  static constexpr double kAcceleratedRatio = 0.5;

  // A measure() taken at `step`, `interval` steps after the previous one.
  void record(int step, int interval, double seconds, const Residual& r);

  // The relative L2 error estimate `bake` stops on (inf until it can be estimated).
  double error_estimate() const { return history_.empty() ? kUnknown : history_.back().error_estimate; }
  double error_estimate_max() const { return history_.empty() ? kUnknown : history_.back().error_estimate_max; }
  const std::vector<CheckPoint>& history() const { return history_; }

  static constexpr double kUnknown = std::numeric_limits<double>::infinity();
  static double round_off_for(Precision p);  // relative change per check that is pure noise
  static double unit_roundoff(Precision p);

 private:
  // ratio: the settled contraction per check, when the estimate found one.
  double tail_estimate(double CheckPoint::*change, double floor, double* ratio) const;
  double rounding_floor(int interval) const;  // interval: steps between the last two checks
  // The trailing changes (equal intervals) no longer fall: fitted ratio per check at least
  // kStalledRatio over the last up to 6, or one of them 0; false with fewer than 4.
  static bool changes_stopped_falling(const std::vector<double>& ys);
  static constexpr double kStalledRatio = 0.8;

  double round_off_, unit_;
  bool half_storage_;  // float16 storage, float32 arithmetic
  double q_hint_ = -1;
  bool accelerated_ = false;
  double settled_q_ = -1;  // last settled contraction per step (-1: none yet)
  std::vector<CheckPoint> history_;
};

}  // namespace lblight
