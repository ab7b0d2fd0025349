// The error estimate (solve/convergence.h), the BiCGStab solver (solve/krylov.h) and the report
// built on them (solve/report.h).
#include <catch2/catch.hpp>

#include <cmath>

#include "lblight/lattice/sun.h"
#include "lblight/solve/convergence.h"
#include "lblight/solve/krylov.h"
#include "lblight/solve/report.h"
#include "tests/support/test_support.h"

using namespace lblight;
using namespace lblight::test;

namespace {
// lblight report on a small box with one plain float32 run of B05. Channel albedos differ, green
// highest (the slowest to converge), so the report's default channel is green.
struct SmallReport {
  Scene scene = parse_scene(R"({"version": 1, "models": [{"name": "m", "density": {"type": "procedural",
      "shape": "box", "resolution": 8}, "material": {"sigma_a": [0.3, 0.02, 0.15], "sigma_s": [0.5, 0.78, 0.65],
      "g": 0}}], "lighting": {"solutions": "5"}, "solver": {"tolerance": 1e-3, "model": "paper"}})",
                            "s.json");
  BakePlan plan = make_plan(scene);
  ReportOptions opt;
  Report report;
  SmallReport() {
    opt.solutions = {5};
    opt.runs = {{SolverMethod::Plain, Precision::Float32}};
    const auto backend = cpu_backend();
    report = make_report(plan, *backend, *backend, opt);
  }
  const ReportCurve& curve() const { return report.curves.at(0); }
};

Residual change(double rel) {
  Residual r;
  r.diff_sq = rel * rel;
  r.total_sq = 1.0;
  r.diff_max = rel;
  r.total_max = 1.0;
  return r;
}
}  // namespace

TEST_CASE("A geometric sequence of changes gives the geometric tail, doubled", "[convergence]") {
  ConvergenceMonitor m(Precision::Float64);
  double c = 1e-2;
  for (int k = 1; k <= 8; ++k, c *= 0.5) m.record(10 * k, 10, 0, change(c));
  // last change 1e-2 * 0.5^7, ratio 0.5: remaining = change * r / (1 - r) = change
  CHECK(m.error_estimate() == Approx(2.0 * 1e-2 * std::pow(0.5, 7)).epsilon(1e-9));
}

TEST_CASE("No estimate while the ratio is still climbing or above 1", "[convergence]") {
  ConvergenceMonitor m(Precision::Float64);
  const double changes[] = {1.0, 0.7, 0.57, 0.42, 0.00114};  // light front leaving the lattice
  int step = 0;
  for (double c : changes) m.record(step += 13, 13, 0, change(c));
  CHECK(std::isinf(m.error_estimate()));
  ConvergenceMonitor grow(Precision::Float64);
  for (int k = 1; k <= 6; ++k) grow.record(10 * k, 10, 0, change(1e-3 * k));
  CHECK(std::isinf(grow.error_estimate()));
  // ratios 0.5, 0.5, 0.52, 0.54, 0.59: the last two differ by 0.05, more than the 0.02 (and
  // 0.1 (1 - r) = 0.041) a settled ratio may move: the slow mode has not taken over yet
  ConvergenceMonitor moving(Precision::Float64);
  double c = 1e-2;
  step = 0;
  moving.record(step += 10, 10, 0, change(c));
  for (double r : {0.5, 0.5, 0.52, 0.54, 0.59}) moving.record(step += 10, 10, 0, change(c *= r));
  CHECK(std::isinf(moving.error_estimate()));
}

TEST_CASE("While the ratio still creeps up, the tail uses the last (largest) ratio", "[convergence]") {
  // settled enough to estimate (steps of 0.005 per check), still rising: the log-linear fit over
  // the last checks lags behind at ~0.8, and the tail must take the last ratio 0.81 or it comes
  // out below the true remaining error
  ConvergenceMonitor m(Precision::Float64);
  double c = 1e-2;
  int step = 0;
  m.record(step += 10, 10, 0, change(c));
  for (double r : {0.78, 0.785, 0.79, 0.795, 0.80, 0.805, 0.81}) m.record(step += 10, 10, 0, change(c *= r));
  CHECK(m.error_estimate() == Approx(2.0 * c * 0.81 / (1 - 0.81)).epsilon(1e-6));
}

TEST_CASE("The estimate never drops below the f_0 reservoir deficit or the rounding floor", "[convergence]") {
  ConvergenceMonitor m(Precision::Float32);
  double c = 1e-3;
  for (int k = 1; k <= 8; ++k, c *= 0.5) {
    Residual r = change(c);
    r.deficit_sq = 1e-6;  // relative deficit 1e-3, far above the tail
    m.record(10 * k, 10, 0, r);
  }
  CHECK(m.error_estimate() >= 1e-3);
  // float32, per-step contraction q = 0.99 settled, then changes at the noise floor:
  ConvergenceMonitor f(Precision::Float32);
  c = 1e-2;
  const double r10 = std::pow(0.99, 10);
  int step = 0;
  for (int k = 0; k < 8; ++k, c *= r10) f.record(step += 10, 10, 0, change(c));
  f.record(step += 10, 10, 0, change(1e-7));
  CHECK(f.error_estimate() >= 5 * 6e-8 / (1 - 0.99) * 0.99);
}

TEST_CASE("float16 storage's rounding floor: incoherent rounding or a slow mode hidden in the noise", "[convergence]") {
  // q = 0.98 per step settled over checks 16 steps apart, then irregular changes at float16's
  // noise level (2e-3 per check). Before: 5 u / (1 - q) = 0.12, which no float16 bake below a
  // tolerance of 0.1 could pass, against a measured 1.6 u (8e-4) from float32's steady state.
  const auto stalled = [](double q, int interval) {
    ConvergenceMonitor f(Precision::Float16);
    double c = 0.2;
    const double r = std::pow(q, interval);
    int step = 0;
    for (int k = 0; k < 8; ++k, c *= r) f.record(step += interval, interval, 0, change(c));
    for (double noise : {1.5e-3, 0.9e-3, 1.4e-3, 1.1e-3, 1.3e-3, 1.0e-3}) f.record(step += interval, interval, 0, change(noise));
    return f.error_estimate();
  };
  const double u = 4.9e-4, r16 = std::pow(0.98, 16);
  // the hidden mode's tail: 2 x 2e-3 x r / (1 - r) = 1.1e-2 (above u / sqrt(1 - q) = 3.5e-3)
  CHECK(stalled(0.98, 16) == Approx(2 * 2e-3 * r16 / (1 - r16)).epsilon(0.05));
  CHECK(stalled(0.98, 16) < 0.1 * 5 * u / (1 - 0.98));
  // checks far apart: the hidden mode's tail is 6e-4, the storage's rounding u / sqrt(1 - q) = 4.9e-3
  CHECK(stalled(0.99, 200) == Approx(u / std::sqrt(1 - 0.99)).epsilon(0.05));
}

TEST_CASE("float16 changes below the noise level that still fall are a transient, not a stall", "[convergence]") {
  // The plant at 64 (B06, 2N = 132 steps, checks 16 apart): float16 and float32 changed alike,
  // 0.36 then 1.3e-2, 5.5e-3, 3.0e-3, 1.6e-3 per check with irregular ratios, true error 7e-3. The
  // last is below float16's noise level (2e-3): taking it for a stall claimed 5e-3.
  ConvergenceMonitor f(Precision::Float16, 0.98);
  int step = 4;
  for (double c : {1.0, 0.89, 0.61, 0.46, 0.36, 1.3e-2, 5.5e-3, 3.0e-3, 1.57e-3}) {
    f.record(step, step == 4 ? 4 : 16, 0, change(c));
    step += 16;
  }
  CHECK(f.error_estimate() == ConvergenceMonitor::kUnknown);  // as float32 says for the same changes
  // once they stop falling (or stop altogether), the rounding floor
  for (double c : {1.4e-3, 1.7e-3, 1.2e-3, 1.5e-3, 1.3e-3, 1.6e-3}) f.record(step += 16, 16, 0, change(c));
  CHECK(f.error_estimate() < ConvergenceMonitor::kUnknown);
  CHECK(f.error_estimate() >= 2e-3);
  f.record(step += 16, 16, 0, change(0.0));
  CHECK(f.error_estimate() >= 4.9e-4 / std::sqrt(1 - 0.98));
}

TEST_CASE("Small changes that still shrink with a settled ratio are signal, not rounding noise", "[convergence]") {
  // A slow mode (thin cloud fringe): changes of ~1e-7 per check, below float32's noise level,
  // contracting by 0.9976 per check. The tail (2 c r / (1 - r) ~ 1e-4) is the estimate, not the
  // rounding floor 5 u / (1 - q) ~ 1.2e-4 (which would keep such a bake from ever stopping).
  ConvergenceMonitor m(Precision::Float32);
  const double r = 0.9976;
  double c = 2e-7;
  for (int k = 1; k <= 8; ++k, c *= r) m.record(11 * k, 11, 0, change(c));
  const double last = c / r;
  CHECK(m.error_estimate() == Approx(2 * last * r / (1 - r)).epsilon(0.02));
  CHECK(m.error_estimate() < 5 * 6e-8 / (1 - std::pow(r, 1.0 / 11)));
}

TEST_CASE("report studies the channel with the highest albedo by default", "[report]") {
  // the slowest channel to converge is where the solver's estimate matters most
  const SmallReport r;
  REQUIRE(r.report.curves.size() == 1);
  CHECK(r.curve().channel == "green");
  CHECK(r.report.references.at(0).channel == "green");
}

TEST_CASE("report runs continue below the tolerance down to tolerance / depth", "[report]") {
  // the curve shows how the error keeps falling past where bake would stop
  const SmallReport r;
  const ReportCurve& c = r.curve();
  CHECK(r.report.tolerance == 1e-3);
  REQUIRE(c.stop_step > 0);
  REQUIRE_FALSE(c.points.empty());
  CHECK(c.points.back().step > c.stop_step);
  CHECK(c.points.back().estimate_l2 < r.report.tolerance / r.opt.depth);
}

TEST_CASE("report's steps to tolerance are where the true error first reaches it", "[report]") {
  const SmallReport r;
  const ReportCurve& c = r.curve();
  const ReportPoint* first = nullptr;
  int below = 0;
  for (const ReportPoint& p : c.points)
    if (p.true_l2 <= r.report.tolerance) {
      if (!first) first = &p;
      ++below;
    }
  REQUIRE(first);
  REQUIRE(below > 1);  // later checks are below it too: the first one counts
  CHECK(c.steps_to_tolerance == first->step);
  CHECK(c.seconds_to_tolerance == first->seconds);
}
