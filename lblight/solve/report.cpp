#include "lblight/solve/report.h"

#include <algorithm>
#include <chrono>
#include <cmath>

#include "lblight/core/error.h"
#include "lblight/solve/bake.h"
#include "lblight/solve/convergence.h"
#include "lblight/solve/krylov.h"

namespace lblight {

std::string ReportRunSpec::label() const {
  return std::string(to_string(method)) + " " + to_string(precision);
}

namespace {

using Clock = std::chrono::steady_clock;

// The model reduced to one solution in one channel.
}  // namespace

ModelPlan single_solution_plan(const ModelPlan& mp, const SolutionPlan& sol, int distinct_channel) {
  ModelPlan sub = mp;
  sub.solutions = {sol};
  sub.solutions[0].derived = false;  // the report solves every solution it studies
  sub.channels = {mp.channels[static_cast<std::size_t>(distinct_channel)]};
  if (sub.ground.on) sub.ground.channel_albedo = {mp.ground.channel_albedo[static_cast<std::size_t>(distinct_channel)]};
  sub.channel_of = {0, 0, 0};
  return sub;
}

namespace {

// float64 on the CPU: BiCGStab to a tiny residual, then plain checks until the estimate is below
// the reference tolerance. Totals in double (from the raw state).
std::vector<double> reference_totals(const ModelPlan& sub, const Backend& cpu, double tolerance,
                                     const RunContext& ctx, ReportReference& info) {
  const auto t0 = Clock::now();
  auto solver = cpu.create(sub.lattice, sub.channels, {Precision::Float64, 1, StoreMode::Auto});
  solver->reset({{0, system_boundary(sub, sub.solutions[0], 0)}});
  ConvergenceMonitor monitor(Precision::Float64);
  std::vector<Residual> r;
  double residual = 1e-10;
  const int k = sub.steps.check_interval;
  for (int round = 0; round < 6; ++round) {
    info.steps += bicgstab(krylov_vectors_of(*solver, cpu.name()), residual, 400 * sub.lattice.dims.longest(), ctx).steps;
    monitor = ConvergenceMonitor(Precision::Float64);
    solver->measure(r);
    for (int c = 0; c < 6; ++c) {
      solver->step_and_measure(k, r);
      info.steps += k;
      monitor.record(info.steps, k, 0, r[0]);
    }
    if (monitor.error_estimate() < tolerance) break;
    residual *= 0.01;
  }
  info.estimate = monitor.error_estimate();
  info.seconds = std::chrono::duration<double>(Clock::now() - t0).count();
  std::vector<double> f;
  StateAccess* state = solver->state_access();
  if (!state) throw Error(ErrorCategory::Unavailable, "the reference backend has no state access");
  state->read_state(0, f);
  const std::size_t n = sub.lattice.dims.count();
  std::vector<double> totals(n, 0.0);
  for (int m = 0; m < 19; ++m)
    for (std::size_t i = 0; i < n; ++i) totals[i] += f[m * n + i];
  return totals;
}

// Records true errors at every check (and Krylov iterate) of a bake of the single-solution plan.
class CurveRecorder final : public BakeObserver {
 public:
  CurveRecorder(const std::vector<double>& reference, ReportCurve& curve) : ref_(reference), curve_(curve) {
    double l2 = 0, mx = 0;
    for (double v : ref_) {
      l2 += v * v;
      mx = std::max(mx, std::fabs(v));
    }
    ref_l2_ = std::sqrt(l2);
    ref_max_ = mx;
    totals_.resize(ref_.size());
  }
  void solution_done(const ModelPlan&, SolutionResult&) override {}
  bool wants_iterates() const override { return true; }
  void inspect(const BakeProgress& ev, LatticeSolver& solver, bool measured) override {
    const auto t0 = Clock::now();
    if (!measured) solver.measure(scratch_);
    solver.read_totals(0, totals_.data());
    double e2 = 0, em = 0;
    for (std::size_t i = 0; i < ref_.size(); ++i) {
      const double d = static_cast<double>(totals_[i]) - ref_[i];
      e2 += d * d;
      em = std::max(em, std::fabs(d));
    }
    ReportPoint p;
    p.step = ev.step;
    p.seconds = ev.seconds - own_seconds_;
    p.true_l2 = std::sqrt(e2) / ref_l2_;
    p.true_max = em / ref_max_;
    p.estimate_l2 = ev.error_estimate;  // unknown for Krylov iterates (bake.cpp)
    p.estimate_max = ev.error_estimate_max;
    curve_.points.push_back(p);
    own_seconds_ += std::chrono::duration<double>(Clock::now() - t0).count();
  }

 private:
  const std::vector<double>& ref_;
  ReportCurve& curve_;
  double ref_l2_ = 0, ref_max_ = 0, own_seconds_ = 0;
  std::vector<float> totals_;
  std::vector<Residual> scratch_;
};

void summarise(ReportCurve& c, double tolerance) {
  for (const ReportPoint& p : c.points) {
    if (c.steps_to_tolerance < 0 && p.true_l2 <= tolerance) {
      c.steps_to_tolerance = p.step;
      c.seconds_to_tolerance = p.seconds;
    }
    if (std::isfinite(p.estimate_l2)) {
      if (p.estimate_l2 < p.true_l2) c.estimate_bounds = false;
      c.worst_ratio = std::max(c.worst_ratio, p.estimate_l2 > 0 ? p.true_l2 / p.estimate_l2 : 0.0);
      if (c.stop_step < 0 && p.estimate_l2 < tolerance) {
        c.stop_step = p.step;
        c.stop_seconds = p.seconds;
        c.stop_true_l2 = p.true_l2;
      }
    }
  }
}

}  // namespace

int slowest_channel(const ModelPlan& mp) {
  int best = 0;
  double albedo = -1;
  for (int c = 0; c < kChannels; ++c) {
    const OpticalParams& p = mp.spec->material.channel[c];
    const double a = p.sigma_t() > 0 ? p.sigma_s / p.sigma_t() : 0;
    if (a > albedo) {
      albedo = a;
      best = c;
    }
  }
  return best;
}

Report make_report(const BakePlan& plan, const Backend& backend, const Backend& reference_backend,
                   const ReportOptions& opt, const RunContext& ctx) {
  if (!reference_backend.supports(Precision::Float64))
    throw Error(ErrorCategory::Unavailable, "the reference backend must store float64 (use the cpu backend)");
  for (const ReportRunSpec& run : opt.runs)  // before any solving: the references take a while
    if (!backend.supports(run.precision))
      throw_invalid("run '" + run.label() + "': the " + backend.name() + " backend does not store " +
                    to_string(run.precision) + "; allowed here: " + supported_precisions(backend));
  for (const ModelPlan& mp : plan.models)
    if (mp.model.first_collision_on())
      throw_invalid("model '" + mp.spec->name + "': report follows the iterates of the lattice state, and "
                    "calibration first_collision's B00 adds its exact uncollided light only at the end; switch "
                    "first_collision off for the report (lblight truth and compare --metric l2 measure it)");
  Report report;
  for (const ModelPlan& mp : plan.models) {
    report.tolerance = mp.steps.tolerance;
    const int colour = opt.channel >= 0 ? opt.channel : slowest_channel(mp);
    const int distinct = mp.channel_of[static_cast<std::size_t>(colour)];
    std::vector<const SolutionPlan*> chosen;
    for (const SolutionPlan& s : mp.solutions)
      if (s.index < 0 || std::find(opt.solutions.begin(), opt.solutions.end(), s.index) != opt.solutions.end())
        chosen.push_back(&s);
    if (chosen.empty()) throw_invalid("model '" + mp.spec->name + "' bakes none of the solutions chosen for the report");
    for (const SolutionPlan* sol : chosen) {
      ModelPlan sub = single_solution_plan(mp, *sol, distinct);
      ReportReference ref{mp.spec->name, sol->grid_name, kChannelNames[colour]};
      ctx.report("model '" + mp.spec->name + "' " + sol->grid_name + " (" + kChannelNames[colour] +
          "): float64 reference on the CPU");
      const std::vector<double> truth =
          reference_totals(sub, reference_backend, opt.reference_tolerance, ctx, ref);
      report.references.push_back(ref);
      for (const ReportRunSpec& run : opt.runs) {
        ReportCurve curve;
        curve.model = mp.spec->name;
        curve.solution = sol->grid_name;
        curve.channel = kChannelNames[colour];
        curve.run = run.label() + " " + backend.name();
        ctx.report("  run: " + curve.run);
        ModelPlan r = sub;
        r.steps.mode = IterationMode::Auto;
        r.steps.method = run.method;
        r.steps.tolerance = mp.steps.tolerance / opt.depth;
        r.steps.precision = run.precision;
        CurveRecorder recorder(truth, curve);
        bake_model(r, backend, {}, recorder, ctx);
        summarise(curve, mp.steps.tolerance);
        report.curves.push_back(std::move(curve));
      }
    }
  }
  return report;
}

}  // namespace lblight
