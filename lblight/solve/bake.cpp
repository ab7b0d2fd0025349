#include "lblight/solve/bake.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <optional>
#include <string>

#include <spdlog/spdlog.h>

#include "lblight/backend/node_rules.h"
#include "lblight/core/error.h"
#include "lblight/core/system_info.h"
#include "lblight/solve/ambient_sum.h"
#include "lblight/solve/dsa.h"
#include "lblight/solve/first_collision.h"
#include "lblight/solve/krylov.h"

namespace lblight {
namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }


// One node's total and its change since the last check, into a check's sums and maxima.
void add_node(Residual& r, double total, double change) {
  r.diff_sq += change * change;
  r.total_sq += total * total;
  r.diff_max = std::max(r.diff_max, std::abs(change));
  r.total_max = std::max(r.total_max, std::abs(total));
}

// How one batch ended.
struct BatchOutcome {
  int steps = 0;
  bool converged = false;
  std::vector<ConvergenceMonitor> monitors;
  // Per system, once its estimate has been below the tolerance (after min_steps): the smallest
  // estimate since (inf before). Further steps only bring the state closer to the fixed point, so
  // that estimate stays a bound while the rest of the batch goes on; without the latch, estimates
  // near the noise level of several systems would all have to dip below the tolerance at once.
  std::vector<double> latched, latched_max;
  std::vector<CheckPoint> worst_history;  // the worst system at every check
  int krylov_iterations = 0;
  double krylov_residual = 0;
  bool dsa_fell_back = false;  // DSA did not pay and plain checks finished the batch
  // Plain iteration by pulses (BatchRunner::pulses): each system's totals, in place of its state's.
  std::vector<std::vector<float>> accumulated;
};

class BatchRunner {
 public:
  // warm: the systems start from a previous solve's state, so no minimum step count applies
  // (BakeOptions::warm).
  BatchRunner(const ModelPlan& mp, LatticeSolver& solver, const RunContext& ctx, BakeObserver& observer,
              std::vector<const SolutionPlan*> solutions, std::size_t systems, bool warm)
      : mp_(mp),
        solver_(solver),
        ctx_(ctx),
        observer_(observer),
        solutions_(std::move(solutions)),
        min_steps_(warm ? 0 : mp.steps.min_steps) {
    out_.monitors.assign(systems, ConvergenceMonitor(mp.steps.precision, 1.0 - mp.steps.decay_hint));
    reset_latches();
    t0_ = Clock::now();
  }

  // Plain iteration x <- T(x) with checks every K steps (docs/model.md sec. 5).
  BatchOutcome plain() {
    const StepPolicy& pol = mp_.steps;
    const bool fixed = pol.mode != IterationMode::Auto;
    const int total = fixed ? pol.fixed_steps : pol.max_steps;
    while (out_.steps < total) {
      // Fixed runs put their checks on the last steps (N, N-K, N-2K, ...), so the final error
      // estimate compares equal intervals.
      int chunk = pol.check_interval;
      if (fixed && out_.steps == 0 && total % pol.check_interval != 0) chunk = total % pol.check_interval;
      chunk = std::min(chunk, total - out_.steps);
      if (check(chunk, total) && !fixed && out_.steps >= min_steps_) {
        out_.converged = true;
        break;
      }
    }
    return std::move(out_);
  }

  // What each system's stored totals add to its state's (first_collision: the exact uncollided
  // light and the credit); the checks and the stop see the sums.
  void set_offsets(std::vector<std::vector<double>> offsets) { offsets_ = std::move(offsets); }

  // Plain iteration from a volume source s held as the systems' states (first_collision, boundary
  // values 0): stepped alone the state is the pulse A^k s, and plain iteration x <- A x + s from
  // x = s is the running sum of the pulses, so its totals are the running sum of the pulses'
  // totals, taken after every step. The same checks and stop as plain(); out.accumulated holds the
  // totals (with the offsets).
  BatchOutcome pulses() {
    const std::size_t systems = out_.monitors.size(), n = mp_.lattice.dims.count();
    sums_ = offsets_;
    sums_.resize(systems);
    for (auto& v : sums_) v.resize(n, 0.0);
    buffer_.resize(n);
    solver_.measure(residuals_);
    for (std::size_t s = 0; s < systems; ++s) add_totals(s, nullptr);
    BatchOutcome out = plain();
    out.accumulated.resize(systems);
    for (std::size_t s = 0; s < systems; ++s) out.accumulated[s].assign(sums_[s].begin(), sums_[s].end());
    return out;
  }

  // BiCGStab rounds, each verified by plain checks with the same error estimate; a round that
  // does not verify is followed by one with a ten times tighter residual.
  // sourced: the systems' states hold a volume source (first_collision), the boundary values are
  // 0, and the checks step x <- A x + b through the Krylov vectors.
  BatchOutcome krylov(bool sourced = false) {
    const StepPolicy& pol = mp_.steps;
    sourced_ = sourced;
    double residual_tolerance = 0.1 * pol.tolerance;
    for (int round = 0; round < 4 && out_.steps < pol.max_steps; ++round) {
      KrylovProgress iterate;
      if (observer_.wants_iterates())
        iterate = [&](const KrylovResult& k) {
          observer_.inspect({&mp_, solutions_, out_.steps + k.steps, pol.max_steps, ConvergenceMonitor::kUnknown,
                             seconds_since(t0_), ConvergenceMonitor::kUnknown},
                            solver_, false);
        };
      const KrylovResult kr =
          bicgstab(*solver_.krylov_vectors(), residual_tolerance, pol.max_steps - out_.steps, ctx_, iterate,
                   !sourced ? KrylovRhs::StepOffset : round == 0 ? KrylovRhs::FromState : KrylovRhs::Kept);
      out_.steps += kr.steps;
      out_.krylov_iterations += kr.iterations;
      out_.krylov_residual = kr.residual;
      if (verify()) break;
      residual_tolerance *= 0.1;
    }
    if (!offsets_.empty()) {  // the stored totals: the state's and the offsets
      out_.accumulated.resize(offsets_.size());
      buffer_.resize(mp_.lattice.dims.count());
      for (std::size_t s = 0; s < offsets_.size(); ++s) {
        solver_.read_totals(static_cast<int>(s), buffer_.data());
        out_.accumulated[s].resize(buffer_.size());
        for (std::size_t i = 0; i < buffer_.size(); ++i)
          out_.accumulated[s][i] = static_cast<float>(buffer_[i] + offsets_[s][i]);
      }
    }
    return std::move(out_);
  }

  // Cycles of LB steps, the last of each followed by a diffusion correction of every system
  // (solve/dsa.h). Each cycle's change of the corrected totals goes to an accelerated monitor
  // (convergence.h): the same tail estimate and latch as plain checks, with the cycle as the
  // interval. corrections: one per system of the batch.
  BatchOutcome dsa(const std::vector<DiffusionCorrection*>& corrections, const DsaSettings& settings) {
    const StepPolicy& pol = mp_.steps;
    StateAccess& state = *solver_.state_access();
    const std::size_t systems = corrections.size(), n = mp_.lattice.dims.count();
    const int m = std::max(2, settings.steps_per_correction);
    // The mean change over the cycle's last `span` steps: 2 cancels light that swaps between
    // opposite directions every step, which a single step's change would take for a residual.
    const int span = std::clamp(settings.span, 1, m);
    // the residual comes from float32 totals (read_totals): their round-off, whatever the storage
    const Precision noise = pol.precision == Precision::Float16 ? Precision::Float16 : Precision::Float32;
    out_.monitors.assign(systems, ConvergenceMonitor::accelerated(noise, settings.expected_contraction));
    std::vector<std::vector<float>> before(systems, std::vector<float>(n)), after = before;
    std::vector<std::vector<double>> last(systems, std::vector<double>(n, 0.0));
    std::vector<double> phi, added;
    std::vector<Residual> cycle(systems);
    while (out_.steps + m <= pol.max_steps) {
      const auto cycle_start = Clock::now();
      solver_.step_and_measure(m - span, residuals_);
      double step_seconds = seconds_since(cycle_start);
      for (std::size_t s = 0; s < systems; ++s) solver_.read_totals(static_cast<int>(s), before[s].data());
      const auto last_steps = Clock::now();
      solver_.step_and_measure(span, residuals_);
      step_seconds += seconds_since(last_steps);
      out_.steps += m;
      for (std::size_t s = 0; s < systems; ++s) {
        solver_.read_totals(static_cast<int>(s), after[s].data());
        const DiffusionSolveStats st = corrections[s]->solve(before[s], after[s], span, phi, &added);
        out_.krylov_iterations += st.iterations;
        state.add_mode(static_cast<int>(s), phi, corrections[s]->shapes(), mp_.lattice.material);
        Residual r = residuals_[s];  // finite flag and reservoir deficit of the last step
        r.diff_sq = r.total_sq = r.diff_max = r.total_max = 0;
        for (std::size_t i = 0; i < n; ++i) {
          const double v = static_cast<double>(after[s][i]) + added[i];
          add_node(r, v, v - last[s][i]);
          last[s][i] = v;
        }
        cycle[s] = r;
      }
      if (record_checks(m, pol.max_steps, cycle, true)) {
        out_.converged = true;
        break;
      }
      if (!pays(seconds_since(cycle_start), step_seconds / m)) {
        // Where diffusion is not what slows the plain iteration (absorbing plants, forward
        // peaks the lattice barely scatters), its steps are cheaper than cycles that do not
        // contract faster: go on with plain checks from here.
        solver_.measure(residuals_);
        out_.monitors.assign(systems, ConvergenceMonitor(pol.precision, 1.0 - pol.decay_hint));
        reset_latches();
        out_.dsa_fell_back = true;
        return plain();
      }
    }
    solver_.measure(residuals_);  // the totals of the corrected state, which the bake stores
    return std::move(out_);
  }

  double seconds() const { return seconds_since(t0_); }

 private:
  // DSA: whether the last cycles (after light has crossed the lattice) shrink the error faster
  // per second than plain steps would, at the plan's slowest plain decay per step.
  bool pays(double cycle_seconds, double step_seconds) const {
    if (out_.steps < min_steps_) return true;
    double worst = 0;
    for (const ConvergenceMonitor& mon : out_.monitors) {
      const auto& h = mon.history();
      if (h.size() < 4) return true;
      for (std::size_t k = h.size() - 3; k < h.size(); ++k)
        if (h[k - 1].change_l2 > 0) worst = std::max(worst, h[k].change_l2 / h[k - 1].change_l2);
    }
    if (!(worst < 1.0)) return false;
    const double dsa_rate = -std::log(worst) / std::max(cycle_seconds, 1e-12);
    const double plain_rate = -std::log1p(-std::min(mp_.steps.decay_hint, 0.999)) / std::max(step_seconds, 1e-12);
    return dsa_rate > plain_rate;
  }

  // After a Krylov solve: a fresh monitor, a baseline measure, then up to six plain checks with
  // the usual estimate; true (and converged) once they show the tolerance.
  bool verify() {
    const StepPolicy& pol = mp_.steps;
    out_.monitors.assign(out_.monitors.size(), ConvergenceMonitor(pol.precision, 1.0 - pol.decay_hint));
    reset_latches();
    std::vector<Residual> ignore;
    solver_.measure(ignore);
    for (int c = 0; c < 6 && out_.steps < pol.max_steps; ++c)
      if (check(std::min(pol.check_interval, pol.max_steps - out_.steps), pol.max_steps)) {
        out_.converged = true;
        return true;
      }
    return false;
  }

  void reset_latches() {
    out_.latched.assign(out_.monitors.size(), ConvergenceMonitor::kUnknown);
    out_.latched_max.assign(out_.monitors.size(), ConvergenceMonitor::kUnknown);
  }

  // Runs `chunk` steps and a measure; true when every system's estimate has been below tolerance.
  bool check(int chunk, int planned) {
    if (!sums_.empty()) return check_pulses(chunk, planned);
    if (sourced_) {
      sourced_steps(*solver_.krylov_vectors(), chunk);
      solver_.measure(residuals_);
      // the change is the state's; the size it is measured against includes the offsets
      buffer_.resize(mp_.lattice.dims.count());
      for (std::size_t s = 0; s < offsets_.size(); ++s) {
        solver_.read_totals(static_cast<int>(s), buffer_.data());
        residuals_[s].total_sq = residuals_[s].total_max = 0;
        for (std::size_t i = 0; i < buffer_.size(); ++i) add_node(residuals_[s], buffer_[i] + offsets_[s][i], 0.0);
      }
    } else {
      solver_.step_and_measure(chunk, residuals_);
    }
    out_.steps += chunk;
    return record_checks(chunk, planned, residuals_, false);
  }

  // pulses(): `chunk` steps, each pulse's totals added; the check sees the running sums and their
  // change over the chunk.
  bool check_pulses(int chunk, int planned) {
    const std::size_t systems = sums_.size();
    changes_.assign(systems, std::vector<double>(sums_[0].size(), 0.0));
    std::vector<bool> finite(systems, true);
    for (int k = 0; k < chunk; ++k) {
      solver_.step_and_measure(1, residuals_);
      for (std::size_t s = 0; s < systems; ++s) {
        add_totals(s, &changes_[s]);
        finite[s] = finite[s] && residuals_[s].finite;
      }
    }
    out_.steps += chunk;
    std::vector<Residual> checks(systems);
    for (std::size_t s = 0; s < systems; ++s) {
      for (std::size_t i = 0; i < sums_[s].size(); ++i) add_node(checks[s], sums_[s][i], changes_[s][i]);
      checks[s].finite = finite[s];
    }
    return record_checks(chunk, planned, checks, false);
  }

  // Adds system s's totals of the last measure to its running sum (and to `change`).
  void add_totals(std::size_t s, std::vector<double>* change) {
    solver_.read_totals(static_cast<int>(s), buffer_.data());
    for (std::size_t i = 0; i < buffer_.size(); ++i) {
      sums_[s][i] += buffer_[i];
      if (change) (*change)[i] += buffer_[i];
    }
  }

  // Records one check per system (`residuals`, `interval` steps after the previous one) and
  // reports progress; true when every system's estimate has been below tolerance. accelerated:
  // min_steps does not apply (DSA: its cycles see light that is still crossing as change).
  bool record_checks(int interval, int planned, const std::vector<Residual>& residuals, bool accelerated) {
    const double secs = seconds_since(t0_);
    double worst = 0, worst_max = 0;
    bool all_latched = true;
    CheckPoint worst_point;
    for (std::size_t s = 0; s < out_.monitors.size(); ++s) {
      out_.monitors[s].record(out_.steps, interval, secs, residuals[s]);
      if (!residuals[s].finite)
        throw Error(ErrorCategory::Internal,
                    "model '" + mp_.spec->name + "': the iteration produced NaN or Inf at step " +
                        std::to_string(out_.steps) +
                        "; this should have been rejected by validation, please report it");
      const CheckPoint& cp = out_.monitors[s].history().back();
      if (s == 0 || cp.error_estimate > worst_point.error_estimate || std::isnan(cp.error_estimate)) worst_point = cp;
      const double e = out_.monitors[s].error_estimate(), em = out_.monitors[s].error_estimate_max();
      if ((accelerated || out_.steps >= min_steps_) && (e < mp_.steps.tolerance || std::isfinite(out_.latched[s]))) {
        out_.latched[s] = std::min(out_.latched[s], e);
        out_.latched_max[s] = std::min(out_.latched_max[s], em);
      }
      all_latched = all_latched && out_.latched[s] < mp_.steps.tolerance;
      worst = std::max(worst, std::min(e, out_.latched[s]));
      worst_max = std::max(worst_max, std::min(em, out_.latched_max[s]));
    }
    out_.worst_history.push_back(worst_point);
    const BakeProgress ev{&mp_, solutions_, out_.steps, planned, worst, secs, worst_max};
    observer_.progress(ev);
    if (!accelerated || observer_.wants_iterates())
      observer_.inspect(ev, solver_, !accelerated);  // DSA: the totals predate the last correction
    ctx_.check_cancelled();
    return all_latched;
  }

  const ModelPlan& mp_;
  LatticeSolver& solver_;
  const RunContext& ctx_;
  BakeObserver& observer_;
  std::vector<const SolutionPlan*> solutions_;
  int min_steps_;
  BatchOutcome out_;
  std::vector<Residual> residuals_;
  Clock::time_point t0_;
  bool sourced_ = false;
  std::vector<std::vector<double>> offsets_, sums_, changes_;  // first_collision
  std::vector<float> buffer_;
};

struct SystemRef {
  int solution;  // index into mp.solutions
  int channel;   // index into mp.channels
};

}  // namespace


// An uneven last batch would step as often as the others with a fraction of the device busy.
int balanced_batch(int total, int capacity, int channels) {
  capacity = std::max(1, capacity);
  channels = std::max(1, channels);
  if (total <= capacity) return std::max(1, total);
  const int batches = (total + capacity - 1) / capacity;
  int even = (total + batches - 1) / batches;
  if (capacity % channels == 0) even = (even + channels - 1) / channels * channels;  // still <= capacity
  return even;
}

namespace {

// Systems a batch should hold before memory is considered (batch_capacity).
int wanted_systems(const ModelPlan& mp, const Backend& backend, const BakeOptions& opt) {
  const int channels = std::max(1, static_cast<int>(mp.channels.size()));
  const int total = static_cast<int>(mp.systems());
  const bool krylov = mp.steps.method == SolverMethod::BiCGStab;
  int want = opt.max_systems > 0 ? opt.max_systems
                                 : backend.preferred_batch(mp.lattice.dims, mp.steps.precision, total);
  want = krylov ? 1 : std::max(1, std::min(want, total));
  // A backend's own choice covers at least one whole solution (its channels share the launch).
  if (!krylov && opt.max_systems <= 0) want = std::max(want, std::min(channels, total));
  return want;
}

std::size_t state_bytes(const ModelPlan& mp, const Backend& backend, StateLayout layout) {
  return layout == StateLayout::InPlace ? backend.bytes_per_system_in_place(mp.lattice.dims, mp.steps.precision)
                                        : backend.bytes_per_system(mp.lattice.dims, mp.steps.precision);
}

// Systems of `per_system` bytes that fit the device's free memory next to the lattice and the
// Krylov vectors (8 more state-sized arrays, about 4 systems' worth); -1 when it is not known.
int systems_that_fit(const ModelPlan& mp, const Backend& backend, std::size_t per_system) {
  const std::size_t avail = backend.available_bytes();
  if (avail == 0) return -1;
  const std::size_t extra = mp.steps.method == SolverMethod::BiCGStab ? 4 * per_system : 0;
  // keep a tenth of the free memory for everything else
  const double usable = 0.9 * static_cast<double>(avail) - static_cast<double>(backend.bytes_per_lattice(mp.lattice.dims) + extra);
  return usable > 0 ? static_cast<int>(usable / static_cast<double>(per_system)) : 0;
}

}  // namespace

StateLayout state_layout(const ModelPlan& mp, const Backend& backend, const BakeOptions& opt) {
  const bool offered = state_bytes(mp, backend, StateLayout::InPlace) > 0;
  if (mp.steps.state) {
    if (*mp.steps.state == StateLayout::InPlace && !offered)
      throw Error(ErrorCategory::Unavailable, "state \"in-place\": the " + backend.name() +
                                                  " backend keeps two levels of lattice state; use \"two-levels\" or "
                                                  "\"auto\" (solver.state or --state)");
    return *mp.steps.state;
  }
  if (!offered) return StateLayout::TwoLevels;
  const int fit = systems_that_fit(mp, backend, state_bytes(mp, backend, StateLayout::TwoLevels));
  const int whole = std::min(wanted_systems(mp, backend, opt),
                             std::max(1, std::min(static_cast<int>(mp.channels.size()), static_cast<int>(mp.systems()))));
  if (fit >= 0 && fit < whole) return StateLayout::InPlace;
  const bool rewrites = mp.steps.method != SolverMethod::Plain;
  return backend.prefers_in_place(mp.lattice, mp.steps.precision, rewrites) ? StateLayout::InPlace
                                                                                 : StateLayout::TwoLevels;
}

// Krylov solves take one system at a time (their vectors belong to system 0).
int batch_capacity(const ModelPlan& mp, const Backend& backend, const BakeOptions& opt) {
  const Dims& d = mp.lattice.dims;
  const StateLayout layout = state_layout(mp, backend, opt);
  const std::size_t per_system = state_bytes(mp, backend, layout);
  const std::size_t fixed = backend.bytes_per_lattice(d);
  const std::size_t avail = backend.available_bytes();
  const int channels = std::max(1, static_cast<int>(mp.channels.size()));
  const int total = static_cast<int>(mp.systems());
  const bool krylov = mp.steps.method == SolverMethod::BiCGStab;
  int want = wanted_systems(mp, backend, opt);
  const std::size_t extra = krylov ? 4 * per_system : 0;
  if (avail > 0) {
    const int fit = systems_that_fit(mp, backend, per_system);
    if (fit < 1)
      throw Error(ErrorCategory::Unavailable,
                  "model '" + mp.spec->name + "': a " + std::to_string(d.nx) + "x" + std::to_string(d.ny) + "x" +
                      std::to_string(d.nz) + " lattice needs " + gib(static_cast<double>(fixed + extra + per_system)) + " on the " +
                      backend.name() + " backend but only " + gib(static_cast<double>(avail)) +
                      " is available" + (layout == StateLayout::InPlace ? std::string(" (with the state in place)") : "") +
                      "; lower the resolution or use a machine with more memory");
    want = std::min(want, fit);
  }
  if (want > channels) want -= want % channels;  // whole solutions per batch
  return balanced_batch(total, want, channels);
}

namespace {

// Per solution, what its channels have produced so far: channels may run in separate batches
// when memory is short or a Krylov solver takes one system at a time. `result` holds the worst
// estimate and the most steps over the channels so far, and their share of the batches' time.
struct PartialSolution {
  SolutionResult result;
  std::vector<std::vector<float>> per_channel;
  std::vector<FluxField> per_channel_flux;  // BakeOptions::moments
  int channels_done = 0;
};

// The systems a model solves (each solution that is not derived, in each distinct channel), in
// solution order.
std::vector<SystemRef> system_queue(const ModelPlan& mp) {
  std::vector<SystemRef> queue;
  for (int s = 0; s < static_cast<int>(mp.solutions.size()); ++s)
    if (!mp.solutions[static_cast<std::size_t>(s)].derived)
      for (int c = 0; c < static_cast<int>(mp.channels.size()); ++c) queue.push_back({s, c});
  return queue;
}

// The end of the batch that starts at `start`: up to `capacity` systems, but never a solution's
// channels split across two batches when they fit in one. `alone` (a solution index, or -1)
// takes a batch of its own: first_collision's B00, whose systems start from a source.
std::size_t batch_end(const std::vector<SystemRef>& queue, std::size_t start, int capacity, int channels,
                      int alone = -1) {
  std::size_t end = std::min(queue.size(), start + static_cast<std::size_t>(capacity));
  if (end < queue.size() && channels <= capacity)
    while (end > start + 1 && queue[end].solution == queue[end - 1].solution) --end;
  for (std::size_t q = start + 1; q < end; ++q)
    if ((queue[q].solution == alone) != (queue[start].solution == alone)) return q;
  return end;
}

// The solution first_collision solves from a source (B00, mp.solutions' index), or -1.
int first_collision_solution(const ModelPlan& mp) {
  if (!mp.model.first_collision_on()) return -1;
  for (std::size_t s = 0; s < mp.solutions.size(); ++s)
    if (mp.solutions[s].index == 0 && !mp.solutions[s].derived) return static_cast<int>(s);
  return -1;
}

// Adds system s of a finished batch (its channel's totals, estimate and time share) to its solution.
void add_channel(PartialSolution& p, const BatchOutcome& outcome, std::size_t s, double seconds,
                 std::vector<float> totals, int channel, bool warm) {
  SolutionResult& r = p.result;
  r.warm_start = warm;
  p.per_channel[static_cast<std::size_t>(channel)] = std::move(totals);
  ++p.channels_done;
  r.iterations = std::max(r.iterations, outcome.steps);
  r.krylov_iterations = std::max(r.krylov_iterations, outcome.krylov_iterations);
  r.krylov_residual = std::max(r.krylov_residual, outcome.krylov_residual);
  r.seconds += seconds;
  const double estimate = std::min(outcome.monitors[s].error_estimate(), outcome.latched[s]);
  if (r.history.empty() || estimate >= r.error_estimate) r.history = outcome.worst_history;
  r.error_estimate = std::max(r.error_estimate, estimate);
  r.error_estimate_max =
      std::max(r.error_estimate_max, std::min(outcome.monitors[s].error_estimate_max(), outcome.latched_max[s]));
  r.converged = r.converged && outcome.converged;
}

StateAccess* state_access_for_warm_start(LatticeSolver& solver, const Backend& backend) {
  StateAccess* state = solver.state_access();
  if (!state)
    throw Error(ErrorCategory::Unavailable, "warm starts: the " + backend.name() +
                                                " backend offers no state access; start every frame from zero");
  return state;
}

// The batch's systems (queue entries first..first+count) set to their kept states, then measured
// once: the first check's change is then against the warm totals, not against zero.
void start_warm(LatticeSolver& solver, StateAccess& state, const WarmStart& warm, std::size_t first, std::size_t count,
                std::vector<double>& buffer) {
  for (std::size_t s = 0; s < count; ++s) {
    const std::vector<float>& kept = warm.states[first + s];
    buffer.assign(kept.begin(), kept.end());
    state.write_state(static_cast<int>(s), buffer);
  }
  std::vector<Residual> baseline;
  solver.measure(baseline);
}

void keep_states(const StateAccess& state, WarmStart& warm, std::size_t first, std::size_t count,
                 std::vector<double>& buffer) {
  for (std::size_t s = 0; s < count; ++s) {
    state.read_state(static_cast<int>(s), buffer);
    warm.states[first + s].assign(buffer.begin(), buffer.end());
  }
}

}  // namespace

std::vector<std::vector<int>> solution_batches(const ModelPlan& mp, const Backend& backend, const BakeOptions& opt) {
  BakeOptions whole = opt;
  whole.solutions.clear();
  const int capacity = batch_capacity(mp, backend, whole);
  const int channels = static_cast<int>(mp.channels.size());
  const std::vector<SystemRef> queue = system_queue(mp);
  std::vector<std::vector<int>> batches;
  for (std::size_t start = 0; start < queue.size();) {
    const std::size_t end = batch_end(queue, start, capacity, channels, first_collision_solution(mp));
    std::vector<int> b;
    for (std::size_t q = start; q < end; ++q) {
      const int index = mp.solutions[static_cast<std::size_t>(queue[q].solution)].index;
      if (b.empty() || b.back() != index) b.push_back(index);
    }
    batches.push_back(b);
    start = end;
  }
  return batches;
}

namespace {

std::string grid_list(const std::vector<int>& indices, const char* sep = " ") {
  std::string s;
  for (int i : indices) s += (s.empty() ? "" : sep) + base_grid_name(i);
  return s;
}

// A unit's solutions: planned for the model, not derived, and whole batches.
void check_solution_subset(const ModelPlan& mp, const std::vector<std::vector<int>>& batches,
                           const std::vector<int>& subset) {
  const std::string model = "model '" + mp.spec->name + "'";
  for (int index : subset) {
    const auto it = std::find_if(mp.solutions.begin(), mp.solutions.end(),
                                 [&](const SolutionPlan& s) { return s.index == index; });
    if (it == mp.solutions.end()) {
      std::vector<int> planned;
      for (const SolutionPlan& s : mp.solutions) planned.push_back(s.index);
      throw_invalid(base_grid_name(index) + " is not a solution of " + model + "; allowed: " + grid_list(planned));
    }
    if (it->derived)
      throw_invalid(base_grid_name(index) + " of " + model + " is the sum of B01..B18, not solved: the merge of "
                    "the units computes it; leave it out");
  }
  std::vector<std::string> groups;
  bool split = false;
  for (const std::vector<int>& b : batches) {
    const auto in = [&](int i) { return std::find(subset.begin(), subset.end(), i) != subset.end(); };
    const bool all = std::all_of(b.begin(), b.end(), in), none = std::none_of(b.begin(), b.end(), in);
    split = split || (!all && !none);
    groups.push_back(grid_list(b, ","));
  }
  if (split) {
    std::string allowed;
    for (const std::string& g : groups) allowed += (allowed.empty() ? "" : " | ") + g;
    throw_invalid("solutions " + grid_list(subset) + " split a batch of " + model +
                  " (a batch runs until its slowest system is done: only whole batches come out as in a whole "
                  "bake); allowed: unions of the batches " + allowed);
  }
}

}  // namespace

void bake_model(const ModelPlan& mp, const Backend& backend, const BakeOptions& opt, BakeObserver& observer,
                const RunContext& ctx) {
  const bool subset = !opt.solutions.empty();
  if (subset) check_solution_subset(mp, solution_batches(mp, backend, opt), opt.solutions);
  if (mp.steps.method == SolverMethod::BiCGStab && mp.steps.mode != IterationMode::Auto)
    throw_invalid("solver method bicgstab needs iterations \"auto\" (it stops on the error estimate)");
  const int capacity = batch_capacity(mp, backend, opt);
  SolverOptions so;
  so.precision = mp.steps.precision;
  so.max_systems = capacity;
  so.layout = state_layout(mp, backend, opt);
  auto solver = backend.create(mp.lattice, mp.channels, so);
  if (mp.steps.method == SolverMethod::BiCGStab) krylov_vectors_of(*solver, backend.name());  // offered, or stop here
  std::vector<std::unique_ptr<DiffusionCorrection>> corrections;  // DSA: one per channel
  const DsaSettings dsa_settings;
  if (mp.steps.method == SolverMethod::Dsa) {
    if (!solver->state_access())
      throw Error(ErrorCategory::Unavailable, "solver method dsa: the " + backend.name() +
                                                  " backend offers no state access; use method plain or bicgstab");
    for (const ChannelMaterials& ch : mp.channels)
      corrections.push_back(std::make_unique<DiffusionCorrection>(mp.lattice, ch, dsa_settings));
  }
  observer.model_started(mp, backend, solver->bytes_in_use(), so.layout);

  const std::vector<SystemRef> queue = system_queue(mp);
  StateAccess* warm_state =
      opt.warm && mp.steps.mode == IterationMode::Auto ? state_access_for_warm_start(*solver, backend) : nullptr;
  // States of another lattice (or plan) cannot start this one: its systems start from zero.
  const bool warm_now = warm_state && opt.warm->dims == mp.lattice.dims && opt.warm->states.size() == queue.size() &&
                        std::none_of(opt.warm->states.begin(), opt.warm->states.end(),
                                     [](const std::vector<float>& f) { return f.empty(); });
  if (warm_state && !warm_now) {
    opt.warm->dims = mp.lattice.dims;
    opt.warm->states.assign(queue.size(), {});
  }
  std::vector<double> state_buffer;
  const int channels = static_cast<int>(mp.channels.size());
  const bool fixed = mp.steps.mode != IterationMode::Auto;
  AmbientSum ambient(mp, /*wanted=*/!subset);
  std::vector<PartialSolution> partial(mp.solutions.size());
  // first_collision: B00 is solved from a source, in a batch of its own (first_collision.h)
  const int sourced_solution = first_collision_solution(mp);
  if (sourced_solution >= 0 && mp.steps.method == SolverMethod::Dsa)
    throw std::logic_error("first_collision with method dsa: refused by plan_steps");
  if (sourced_solution >= 0 && !solver->state_access())
    throw Error(ErrorCategory::Unavailable, "calibration first_collision: the " + backend.name() +
                                                " backend offers no state access to hold its source; switch "
                                                "first_collision off or use the cpu or cuda backend");
  for (std::size_t s = 0; s < partial.size(); ++s) {
    partial[s].result.plan = mp.solutions[s];
    partial[s].result.converged = true;  // until a channel does not
    partial[s].per_channel.resize(mp.channels.size());
    partial[s].per_channel_flux.resize(mp.channels.size());
  }
  // moments: read from the final states (flux.h)
  const bool moments = opt.moments && solver->state_access() != nullptr;
  if (opt.moments && !moments)
    spdlog::warn("model '{}': the {} backend gives no access to its states, so no flux (moments) is written; "
                 "render such a bake with --scattering isotropic",
                 mp.spec->name, backend.name());
  std::optional<SolutionResult> sourced_b00;  // moments: held until the directional solutions' flux is summed

  for (std::size_t start = 0; start < queue.size();) {
    const std::size_t end = batch_end(queue, start, capacity, channels, sourced_solution);
    const bool sourced = queue[start].solution == sourced_solution;
    const int first = mp.solutions[static_cast<std::size_t>(queue[start].solution)].index;
    if (subset && std::find(opt.solutions.begin(), opt.solutions.end(), first) == opt.solutions.end()) {
      start = end;  // another unit's batch (whole batches only: checked above)
      continue;
    }
    std::vector<SystemSpec> batch;
    std::vector<const SolutionPlan*> batch_solutions;
    for (std::size_t q = start; q < end; ++q) {
      const SolutionPlan* sp = &mp.solutions[static_cast<std::size_t>(queue[q].solution)];
      // first_collision: B00's light enters through its source only
      const int ch = queue[q].channel;
      batch.push_back({ch, sourced ? std::array<double, 19>{} : system_boundary(mp, *sp, ch)});
      if (batch_solutions.empty() || batch_solutions.back() != sp) batch_solutions.push_back(sp);
    }

    solver->reset(batch);
    // first_collision: the sources as the states, and what the stored totals add to the lattice's
    // (the exact uncollided light and the credit; the boundary's value on the boundary layer)
    std::vector<std::vector<double>> offsets;
    if (sourced) {
      std::vector<std::array<double, kMaxMaterials>> sigma_t;
      for (const SystemSpec& spec : batch) sigma_t.push_back(model_extinction(channel_optics(mp, spec.channel), mp.model));
      offsets = exact_uncollided(mp.lattice, sigma_t, base_solution_uncollided(0), kUncollidedDirections, ctx);
      const SolutionPlan& sp = *batch_solutions.front();
      const Dims& d = mp.lattice.dims;
      for (std::size_t s = 0; s < batch.size(); ++s) {
        const int ch = batch[s].channel;
        FirstCollisionSource src = first_collision_source(mp.lattice, channel_optics(mp, ch), mp.model,
                                                          mp.channels[static_cast<std::size_t>(ch)], sp.boundary);
        solver->state_access()->write_state(static_cast<int>(s), src.state);
        const double open_air = boundary_total(system_boundary(mp, sp, ch));
        for (int z = 0; z < d.nz; ++z)
          for (int y = 0; y < d.ny; ++y)
            for (int x = 0; x < d.nx; ++x) {
              const std::size_t i = d.index(x, y, z);
              offsets[s][i] = d.is_boundary(x, y, z) ? open_air : offsets[s][i] + src.credit[i];
            }
      }
    }
    const bool warm_batch = warm_now && !sourced;  // a source is B00's start
    if (warm_batch) start_warm(*solver, *warm_state, *opt.warm, start, batch.size(), state_buffer);
    BatchRunner runner(mp, *solver, ctx, observer, batch_solutions, batch.size(), warm_batch);
    runner.set_offsets(std::move(offsets));
    std::vector<DiffusionCorrection*> batch_corrections;
    for (const SystemSpec& spec : batch)
      if (!corrections.empty()) batch_corrections.push_back(corrections[static_cast<std::size_t>(spec.channel)].get());
    const BatchOutcome outcome = mp.steps.method == SolverMethod::BiCGStab ? runner.krylov(sourced)
                                 : mp.steps.method == SolverMethod::Dsa    ? runner.dsa(batch_corrections, dsa_settings)
                                 : sourced                                 ? runner.pulses()
                                                                           : runner.plain();
    const double batch_seconds = runner.seconds();
    observer.memory_in_use(mp, solver->bytes_in_use());
    if (warm_state) keep_states(*warm_state, *opt.warm, start, batch.size(), state_buffer);

    // Collect each system's totals; a solution is done once all its channels are.
    for (std::size_t s = 0; s < batch.size(); ++s) {
      PartialSolution& p = partial[static_cast<std::size_t>(queue[start + s].solution)];
      std::vector<float> totals(mp.lattice.dims.count());
      if (!outcome.accumulated.empty())
        totals = outcome.accumulated[s];
      else
        solver->read_totals(static_cast<int>(s), totals.data());
      if (moments && !sourced) {
        solver->state_access()->read_state(static_cast<int>(s), state_buffer);
        p.per_channel_flux[static_cast<std::size_t>(batch[s].channel)] =
            state_flux(mp.lattice, mp.channels[static_cast<std::size_t>(batch[s].channel)], state_buffer);
      }
      add_channel(p, outcome, s, batch_seconds / static_cast<double>(batch.size()), std::move(totals),
                  batch[s].channel, warm_batch);
      if (p.channels_done < channels) continue;
      SolutionResult r = std::move(p.result);
      r.converged = !fixed && r.converged;
      for (int c = 0; c < kChannels; ++c) {
        r.totals[c] = p.per_channel[static_cast<std::size_t>(mp.channel_of[c])];
        if (!p.per_channel_flux[static_cast<std::size_t>(mp.channel_of[c])][0].empty())
          r.flux[c] = p.per_channel_flux[static_cast<std::size_t>(mp.channel_of[c])];
      }
      p = PartialSolution{};
      ambient.add(r);
      if (moments && sourced)
        sourced_b00 = std::move(r);
      else
        observer.solution_done(mp, r);
    }
    start = end;
  }
  if (sourced_b00) {
    ambient.fill_flux(*sourced_b00);
    observer.solution_done(mp, *sourced_b00);
  }
  ambient.finish(observer);
}

}  // namespace lblight
